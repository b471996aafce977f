// Loads each GLB with three.js's GLTFLoader in Node and prints one JSON line per file:
// {"file", "meshes": [{name, alphaTest, transparent, morph, weights, vertices, indexCount}]}.
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
    meshes.push({
      name: o.name,
      alphaTest: m.alphaTest,
      transparent: m.transparent,
      vertexColors: m.vertexColors,
      color: m.color.toArray(),
      morph: g.morphAttributes.position ? g.morphAttributes.position.length : 0,
      weights: o.morphTargetInfluences ? Array.from(o.morphTargetInfluences) : [],
      vertices: g.attributes.position.count,
      indexCount: g.index ? g.index.count : 0,
      box: [box.min.toArray(), box.max.toArray()],
    });
  });
  console.log(JSON.stringify({ file, meshes }));
}
console.error = quietError;
