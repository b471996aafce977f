// Loads GLB files into Babylon.js (NullEngine, no browser) and plays each animation group alone
// to its last frame, printing the morph target influences Babylon then gives every mesh that
// has morph targets, while the loader still reads the coarser levels (`loading`) and once it has
// read every level (`clips`; it ends on LOD 0, as a page sees it for good): one JSON line per
// file, { file, loading: CLIPS, clips: CLIPS }, CLIPS = { name: { mesh: [influence, …] } }.
// Usage: node babylon_weights.mjs FILE...
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
BABYLON.Logger.LogLevels = BABYLON.Logger.ErrorLogLevel;

const engine = new BABYLON.NullEngine();
for (const file of process.argv.slice(2)) {
  const scene = new BABYLON.Scene(engine);
  const data = await readFile(file);
  // the loader reads MSFT_lod progressively: wait until it has loaded every level (it ends on
  // LOD 0), as a page does before playing a clip
  let loader = null;
  const activated = BABYLON.SceneLoader.OnPluginActivatedObservable.add((plugin) => {
    if (plugin.name === 'gltf') loader = plugin;
  });
  await BABYLON.SceneLoader.ImportMeshAsync('', '', new Uint8Array(data), scene, null, '.glb');
  const play = () => {
    const clips = {};
    for (const group of scene.animationGroups) {
      for (const other of scene.animationGroups) other.stop();
      group.start(false);
      group.goToFrame(group.to);
      group.pause();
      const meshes = {};
      for (const m of scene.meshes.filter((m) => m.morphTargetManager)) {
        const t = m.morphTargetManager;
        meshes[m.name] = [...Array(t.numTargets).keys()].map((i) => t.getTarget(i).influence);
      }
      clips[group.name] = meshes;
    }
    return clips;
  };
  // while the coarser levels are all there is, and once LOD 0 has replaced them
  const loading = play();
  if (loader) await loader.whenCompleteAsync();
  BABYLON.SceneLoader.OnPluginActivatedObservable.remove(activated);
  const clips = play();
  console.log(JSON.stringify({ file, loading, clips }));
  scene.dispose();
}
engine.dispose();
