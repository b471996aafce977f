// What the extrusion stream of a compact bake pays for, measured without writing a file: the
// stream of an uncompressed bake (`shellbake bake MESH --compress none`) rebuilt with other
// heights or directions and compressed with meshoptimizer's vertex codec (version 0, as
// EXT_meshopt_compression reads it). One line per candidate: its compressed bytes.
//
//   node tests/bench/extrusion_entropy.mjs baked.glb
//
// Candidates, each a vector of whole position steps as the file stores them:
// - every vertex at the longest extrusion, along its own direction (no inversion guard);
// - the heights rounded down to 2, 4, 8 or 16 levels of the longest;
// - the directions averaged with their neighbours' (welded by stored position) over 5, 20 or
//   100 rounds, with no face constraint, at the longest extrusion.
import fs from 'fs';
import { MeshoptEncoder as E } from 'meshoptimizer';

await E.ready;
const file = process.argv[2];
if (!file) throw new Error('usage: node extrusion_entropy.mjs baked.glb');
const glb = fs.readFileSync(file);
const jsonLength = glb.readUInt32LE(12);
const doc = JSON.parse(glb.subarray(20, 20 + jsonLength).toString());
const bin = glb.subarray(20 + jsonLength + 8);
const view = (name) => {
  const v = doc.bufferViews.filter((v) => v.name === name);
  if (v.length < 1) throw new Error(`${file}: no '${name}' view (a compact, uncompressed bake)`);
  return Uint8Array.from(bin.subarray(v[0].byteOffset || 0, (v[0].byteOffset || 0) + v[0].byteLength)).buffer;
};
const ext = new Int16Array(view('extrusion'));
const pos = new Int16Array(view('position'));
const idx = new Uint32Array(view('indices'));
const nv = ext.length / 4;
const bytes = (a) => E.encodeVertexBufferLevel(new Uint8Array(a.buffer), nv, 8, 2, 0).length;
const length = Float64Array.from({ length: nv }, (_, k) => Math.hypot(ext[4 * k], ext[4 * k + 1], ext[4 * k + 2]));
const longest = length.reduce((a, b) => Math.max(a, b), 0);
const stream = (direction, height) => {
  const out = new Int16Array(4 * nv);
  for (let k = 0; k < nv; k++) for (let c = 0; c < 3; c++) out[4 * k + c] = Math.round(direction(k, c) * height(k));
  return out;
};
const own = (k, c) => (length[k] > 0 ? ext[4 * k + c] / length[k] : 0);
console.log(`as written (longest ${longest.toFixed(0)} steps): ${bytes(ext)}`);
console.log(`every vertex at the longest: ${bytes(stream(own, () => longest))}`);
for (const n of [2, 4, 8, 16]) {
  const step = longest / n;
  console.log(`heights in ${n} levels: ${bytes(stream(own, (k) => Math.max(1, Math.floor(length[k] / step)) * step))}`);
}
// neighbours through welded positions
const first = new Map();
const rep = Int32Array.from({ length: nv }, (_, k) => {
  const key = `${pos[4 * k]},${pos[4 * k + 1]},${pos[4 * k + 2]}`;
  if (!first.has(key)) first.set(key, k);
  return first.get(key);
});
const ring = Array.from({ length: nv }, () => []);
for (let t = 0; t < idx.length; t += 3) {
  for (let i = 0; i < 3; i++) {
    const a = rep[idx[t + i]];
    const b = rep[idx[t + ((i + 1) % 3)]];
    ring[a].push(b);
    ring[b].push(a);
  }
}
let d = Float64Array.from({ length: 3 * nv }, (_, i) => own(Math.floor(i / 3), i % 3));
let done = 0;
for (const rounds of [5, 20, 100]) {
  for (; done < rounds; done++) {
    const next = new Float64Array(3 * nv);
    for (let k = 0; k < nv; k++) {
      if (rep[k] !== k) continue;
      const s = [d[3 * k], d[3 * k + 1], d[3 * k + 2]];
      for (const j of ring[k]) for (let c = 0; c < 3; c++) s[c] += d[3 * j + c];
      const l = Math.hypot(...s) || 1;
      for (let c = 0; c < 3; c++) next[3 * k + c] = s[c] / l;
    }
    for (let k = 0; k < nv; k++) for (let c = 0; c < 3; c++) next[3 * k + c] = next[3 * rep[k] + c];
    d = next;
  }
  console.log(`directions smoothed over ${rounds} rounds: ${bytes(stream((k, c) => d[3 * k + c], () => longest))}`);
}
