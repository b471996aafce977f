//! The core stages every surface runs, in plan order: orient and weld the mesh, tessellate it
//! when asked, cut it where the asset's colour has detail finer than its triangles, build the extrusion frames, smooth and clamp the heights (with the collision
//! bound), bake the strand mask and its tiling, stack the shells, cull what no layer shows and
//! build the LOD chain. Skinned input keeps its skin (the skeleton is `model::skeleton`).

pub mod clamp;
pub mod colour;
pub mod cull;
pub mod frames;
pub mod lod;
pub mod merge;
pub mod orient;
pub mod shells;
pub mod strands;
pub mod tessellate;
pub mod tiling;
pub mod weld;
