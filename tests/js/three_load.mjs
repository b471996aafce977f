// Loads each GLB with three.js's GLTFLoader in Node and prints one JSON line per file:
// {"file", "meshes": [{name, node, alphaTest, transparent, morph, weights, vertices, indexCount,
// box, drawn}]}: `node` is the glTF node's name, `drawn` the vertices as drawn (each morph
// target's displacement times its weight added, the node transforms applied; no skinning) as
// {box, centroid, displacement}, against which tests/bevy.rs holds what Bevy's loader makes.
// Textures need a browser to decode; the loader is given a stub that never resolves images,
// which GLTFLoader reports and skips — geometry, materials and morph targets are still checked.
// Usage: node three_load.mjs FILE...
import { readFile } from 'node:fs/promises';
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';

// Minimal globals GLTFLoader touches in Node.
globalThis.self = globalThis;
globalThis.window = globalThis;
globalThis.createImageBitmap = undefined;
if (typeof globalThis.document === 'undefined') {
  globalThis.document = { createElementNS: () => ({ style: {} }) };
}
const quietError = console.error;
console.error = () => {};
console.warn = () => {};

function parse(loader, buffer) {
  return new Promise((resolve, reject) => loader.parse(buffer, '', resolve, reject));
}

/// Mesh `o`'s vertices as drawn — base positions plus every morph target's displacement times its
/// influence (three.js's targets are relative for glTF), in world space, no skinning: their box,
/// centroid and mean distance from rest.
function drawnBox(o) {
  const g = o.geometry;
  const pos = g.attributes.position;
  const targets = g.morphAttributes.position || [];
  const w = o.morphTargetInfluences || [];
  const v = new THREE.Vector3();
  const rest = new THREE.Vector3();
  const box = new THREE.Box3();
  const centroid = new THREE.Vector3();
  let displacement = 0;
  for (let i = 0; i < pos.count; i++) {
    v.fromBufferAttribute(pos, i);
    rest.copy(v).applyMatrix4(o.matrixWorld);
    for (let t = 0; t < targets.length; t++) {
      if (w[t]) {
        v.x += w[t] * targets[t].getX(i);
        v.y += w[t] * targets[t].getY(i);
        v.z += w[t] * targets[t].getZ(i);
      }
    }
    v.applyMatrix4(o.matrixWorld);
    box.expandByPoint(v);
    centroid.add(v);
    displacement += v.distanceTo(rest);
  }
  const n = Math.max(pos.count, 1);
  return {
    box: [box.min.toArray(), box.max.toArray()],
    centroid: centroid.divideScalar(n).toArray(),
    displacement: displacement / n,
  };
}

for (const file of process.argv.slice(2)) {
  const bytes = await readFile(file);
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  const loader = new GLTFLoader();
  let gltf;
  try {
    gltf = await parse(loader, buffer);
  } catch (e) {
    console.log(JSON.stringify({ file, error: String(e && e.message ? e.message : e) }));
    continue;
  }
  const meshes = [];
  gltf.scene.updateMatrixWorld(true);
  gltf.scene.traverse((o) => {
    if (!o.isMesh) return;
    const g = o.geometry;
    const m = o.material;
    const box = new THREE.Box3().setFromObject(o);
    const assoc = gltf.parser.associations;
    const at = assoc.get(o) && assoc.get(o).nodes !== undefined ? assoc.get(o) : assoc.get(o.parent);
    const nodeIndex = at ? at.nodes : undefined;
    const drawn = drawnBox(o);
    meshes.push({
      name: o.name,
      node: nodeIndex === undefined ? null : (gltf.parser.json.nodes[nodeIndex].name ?? null),
      alphaTest: m.alphaTest,
      transparent: m.transparent,
      vertexColors: m.vertexColors,
      color: m.color.toArray(),
      morph: g.morphAttributes.position ? g.morphAttributes.position.length : 0,
      weights: o.morphTargetInfluences ? Array.from(o.morphTargetInfluences) : [],
      vertices: g.attributes.position.count,
      indexCount: g.index ? g.index.count : 0,
      box: [box.min.toArray(), box.max.toArray()],
      drawn,
    });
  });
  console.log(JSON.stringify({ file, meshes }));
}
console.error = quietError;
