// Loads GLB files into Babylon.js (NullEngine, no browser) and plays each animation group alone
// to its last frame, printing the morph target influences Babylon then gives every mesh that
// has morph targets: one JSON line per file, { file, clips: { name: { mesh: [influence, …] } } }.
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
  await BABYLON.SceneLoader.ImportMeshAsync('', '', new Uint8Array(data), scene, null, '.glb');
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
  console.log(JSON.stringify({ file, clips }));
  scene.dispose();
}
engine.dispose();
