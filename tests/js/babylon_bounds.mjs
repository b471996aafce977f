// Loads GLB files into Babylon.js (NullEngine, no browser) and prints the world bounds Babylon
// computes, as it frames cameras and culls: one JSON line per file,
// { file, all: {min, max}, fur: {min, max} | null, meshes, lod: {enabled, levels, meshes} }.
// `fur` covers the meshes under a node whose extras carry `shellbake` or `shellbake_fur` (the fur
// shellbake added to an asset). `lod`: whether the loader's MSFT_lod extension was on, how many
// levels it loaded (its onNodeLODsLoadedObservable, coarsest first), and the meshes with vertices
// left once loading completed (Babylon loads MSFT_lod levels progressively and ends on LOD 0).
// Usage: node babylon_bounds.mjs FILE...
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';

// the UMD builds register the loaders on the global BABYLON
const require = createRequire(import.meta.url);
const BABYLON = require('babylonjs');
globalThis.BABYLON = BABYLON;
const loaders = require('babylonjs-loaders');
if (!BABYLON.SceneLoader.IsPluginForExtensionAvailable('.glb')) {
  BABYLON.SceneLoader.RegisterPlugin(new loaders.GLTFFileLoader());
}

const engine = new BABYLON.NullEngine();
for (const file of process.argv.slice(2)) {
  const scene = new BABYLON.Scene(engine);
  const lod = { enabled: false, levels: 0, meshes: 0 };
  let loader = null;
  const activated = BABYLON.SceneLoader.OnPluginActivatedObservable.add((plugin) => {
    if (plugin.name !== 'gltf') return;
    loader = plugin;
    plugin.onExtensionLoadedObservable.add((ext) => {
      if (ext.name !== 'MSFT_lod') return;
      lod.enabled = ext.enabled;
      ext.onNodeLODsLoadedObservable.add(() => { lod.levels += 1; });
    });
  });
  const bytes = await readFile(file);
  const url = 'data:model/gltf-binary;base64,' + bytes.toString('base64');
  const result = await BABYLON.SceneLoader.ImportMeshAsync('', '', url, scene, null, '.glb');
  const isFur = (node) => {
    for (let n = node; n; n = n.parent) {
      const extras = n.metadata && n.metadata.gltf && n.metadata.gltf.extras;
      if (extras && (extras.shellbake !== undefined || extras.shellbake_fur !== undefined)) return true;
    }
    return false;
  };
  const box = (meshes) => {
    if (!meshes.length) return null;
    const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
    for (const m of meshes) {
      m.computeWorldMatrix(true);
      m.refreshBoundingInfo();
      const b = m.getBoundingInfo().boundingBox;
      const lo = b.minimumWorld.asArray(), hi = b.maximumWorld.asArray();
      for (let k = 0; k < 3; k++) { min[k] = Math.min(min[k], lo[k]); max[k] = Math.max(max[k], hi[k]); }
    }
    return { min, max };
  };
  const meshes = result.meshes.filter((m) => m.getTotalVertices() > 0);
  const bounds = { all: box(meshes), fur: box(meshes.filter(isFur)), bare: box(meshes.filter((m) => !isFur(m))) };
  await loader.whenCompleteAsync();
  BABYLON.SceneLoader.OnPluginActivatedObservable.remove(activated);
  lod.meshes = scene.meshes.filter((m) => !m.isDisposed() && m.getTotalVertices() > 0).length;
  console.log(JSON.stringify({
    file,
    ...bounds,
    meshes: meshes.length,
    lod,
  }));
  scene.dispose();
}
engine.dispose();
