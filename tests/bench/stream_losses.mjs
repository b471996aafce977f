// What each lossy encoding of a stream would save, measured on a baked file without writing it:
// the streams of an uncompressed compact bake (`shellbake bake MESH --compress none`) re-encoded
// and compressed with meshoptimizer's vertex codec (version 0, as EXT_meshopt_compression reads
// it). Prints one line per candidate: the stream's compressed bytes and, where it is a grid, the
// largest error against the stored values.
//
//   node tests/bench/stream_losses.mjs baked.glb
//
// Candidates:
// - texture coordinates as integer levels of 14 to 11 bits (unnormalized `u16`, which glTF-Transform's
//   `quantize` leaves alone as out of [0, 1]), against the file's 16-bit normalized levels;
// - the extrusion as `i16` counts of 2 to 16 position steps (needs layer weights above 1), and
//   through the EXPONENTIAL filter with one exponent per component (float targets, weights in
//   [0, 1]) at 12 to 7 mantissa bits;
// - normals through the octahedral filter at 8 (as written), 7 and 6 bits.
import fs from 'fs';
import { MeshoptEncoder as E } from 'meshoptimizer';

await E.ready;
const file = process.argv[2];
if (!file) throw new Error('usage: node stream_losses.mjs baked.glb');
const glb = fs.readFileSync(file);
const jsonLength = glb.readUInt32LE(12);
const doc = JSON.parse(glb.subarray(20, 20 + jsonLength).toString());
const bin = glb.subarray(20 + jsonLength + 8);
const one = (name) => {
  const v = doc.bufferViews.filter((v) => v.name === name);
  if (v.length !== 1) throw new Error(`${file}: expected one '${name}' view (a compact, uncompressed bake), found ${v.length}`);
  return Uint8Array.from(bin.subarray(v[0].byteOffset || 0, (v[0].byteOffset || 0) + v[0].byteLength)).buffer;
};
const nrm = new Int8Array(one('normal'));
const uvq = new Uint16Array(one('texcoord'));
const ext = new Int16Array(one('extrusion'));
const nv = ext.length / 4;
const u8 = (a) => new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
const vertexBytes = (a, stride) => E.encodeVertexBufferLevel(u8(a), nv, stride, 2, 0).length;
const line = (what, bytes, error) => console.log(`${what}: ${bytes}${error === undefined ? '' : ` (error up to ${error})`}`);

line('texcoord, 16-bit normalized levels (as written)', vertexBytes(uvq, 4));
for (const bits of [14, 13, 12, 11]) {
  const levels = (1 << bits) - 1;
  line(`texcoord, ${bits}-bit integer levels`, vertexBytes(Uint16Array.from(uvq, (v) => Math.round((v * levels) / 65535)), 4));
}
let largest = 0;
for (let k = 0; k < nv; k++) for (let c = 0; c < 3; c++) largest = Math.max(largest, Math.abs(ext[4 * k + c]));
line(`extrusion, i16 position steps (as written; largest component ${largest} steps)`, vertexBytes(ext, 8));
for (const k of [2, 4, 8, 16]) {
  line(`extrusion, i16 counts of ${k} steps`, vertexBytes(Int16Array.from(ext, (v) => Math.round(v / k)), 8), `${k / 2} steps`);
}
const f = new Float32Array(3 * nv);
for (let k = 0; k < nv; k++) for (let c = 0; c < 3; c++) f[3 * k + c] = ext[4 * k + c];
for (const bits of [12, 11, 10, 9, 8, 7]) {
  const encoded = E.encodeFilterExp(f, nv, 12, bits, 'SharedComponent');
  const words = new Int32Array(encoded.buffer, encoded.byteOffset, encoded.byteLength / 4);
  let error = 0;
  words.forEach((w, i) => (error = Math.max(error, Math.abs(((w << 8) >> 8) * 2 ** (w >> 24) - f[i]))));
  line(`extrusion, exponential filter, ${bits} mantissa bits`, E.encodeVertexBufferLevel(encoded, nv, 12, 2, 0).length, `${error} steps`);
}
const unit = Float32Array.from(nrm, (c) => Math.max(c / 127, -1));
for (const bits of [8, 7, 6]) line(`normal, octahedral ${bits} bits`, vertexBytes(E.encodeFilterOct(unit, nv, 4, bits), 4));
