// What dropping the texture-coordinate stream of a generated box projection would save, measured
// on a baked file without writing the layout: the streams of an uncompressed compact bake
// (`shellbake bake MESH --compress none`) are re-arranged as each candidate layout would store
// them and compressed with meshoptimizer's codecs (vertex codec version 0 as
// EXT_meshopt_compression reads it, and version 1 as KHR_meshopt_compression does; normals
// through the octahedral filter at 8 bits, as shellbake writes them). Prints a Markdown table.
//
//   node tests/bench/box_uv_alias.mjs baked.glb
//
// Candidates:
// - "as written": the file's own streams, compressed (matches the bake's `--report` streams);
// - "texcoord from position, planes apart": every vertex keeps its projection plane's copy, and
//   each plane's vertices are stored with their axes permuted under a node rotation, so that a
//   TEXCOORD_0 accessor reads the first two position components: no texture-coordinate stream;
// - "texcoord from position, shared": copies that differ only by their coordinates are merged
//   where glTF's 4-byte attribute alignment allows — (x, y) serves the Z plane, (z, w) the X plane
//   with w = y and the Y plane with w = x, so only X–Y seam vertices stay apart — and the
//   position stream carries w. One accessor offset per primitive, so each layer draws two
//   primitives: A (the X and Y planes' faces) and B (the Z plane's), each index stream split in
//   two, vertices in first use over A's lists, then B's; a vertex only B uses repeats the w
//   before it (the codec stores a zero change). The row before it merges the same way but keeps
//   each stream whole: what the split costs. The row after it, the same without w (no valid
//   layout), shows what w costs.
// Each vertex's plane is found from the file itself: its coordinates are a linear function of two
// position components, the same for every vertex of a plane.
import fs from 'fs';
import { MeshoptEncoder as E } from 'meshoptimizer';

await E.ready;
const file = process.argv[2];
if (!file) throw new Error('usage: node box_uv_alias.mjs baked.glb');
const glb = fs.readFileSync(file);
const jsonLength = glb.readUInt32LE(12);
const doc = JSON.parse(glb.subarray(20, 20 + jsonLength).toString());
const bin = glb.subarray(20 + jsonLength + 8);
const views = (name) => doc.bufferViews.filter((v) => v.name === name);
const bytes = (v) => Uint8Array.from(bin.subarray(v.byteOffset || 0, (v.byteOffset || 0) + v.byteLength)).buffer;
const one = (name) => {
  const v = views(name);
  if (v.length !== 1) throw new Error(`${file}: expected one '${name}' view (a compact, uncompressed bake), found ${v.length}`);
  return bytes(v[0]);
};
const indices = views('indices').map((v) => new Uint32Array(bytes(v)));
// the vertices triangles use: the streams end with the box vertices no triangle draws
// (`pack::streams::BOX_VERTICES`), which no layout would change
const nv = 1 + indices.reduce((m, ix) => ix.reduce((a, i) => Math.max(a, i), m), 0);
const pos = new Int16Array(one('position')).slice(0, 4 * nv);
const nrm = new Int8Array(one('normal')).slice(0, 4 * nv);
const uvq = new Uint16Array(one('texcoord')).slice(0, 2 * nv);
const ext = new Int16Array(one('extrusion')).slice(0, 4 * nv);
const mat = doc.materials.find((m) => m.pbrMetallicRoughness?.baseColorTexture?.extensions?.KHR_texture_transform);
const tt = mat.pbrMetallicRoughness.baseColorTexture.extensions.KHR_texture_transform;
const U = (k) => tt.offset[0] + (tt.scale[0] * uvq[2 * k]) / 65535;
const V = (k) => tt.offset[1] + (tt.scale[1] * uvq[2 * k + 1]) / 65535;
const u8 = (a) => new Uint8Array(a.buffer, a.byteOffset, a.byteLength);

// the most frequent value of `f` over a sample, in buckets of `q`
const mode = (values, q) => {
  const seen = new Map();
  let best = 0, value = 0;
  for (const x of values) {
    const k = Math.round(x / q), c = (seen.get(k) || 0) + 1;
    seen.set(k, c);
    if (c > best) [best, value] = [c, k * q];
  }
  return value;
};
let seed = 1;
const random = () => (seed = (seed * 1103515245 + 12345) % 2147483648) / 2147483648;
// scale of a coordinate against a position component: the ratio over far-apart vertex pairs
const scale = (coord, axis, sign) => {
  const r = [];
  for (let t = 0; t < 400000; t++) {
    const a = Math.floor(random() * nv), b = Math.floor(random() * nv);
    const d = pos[4 * b + axis] - pos[4 * a + axis];
    if (Math.abs(d) > 3000) r.push((sign * (coord(b) - coord(a))) / d);
  }
  return mode(r, 2e-8);
};
const su = scale(U, 0, 1), sv = scale(V, 1, -1);
const all = Array.from({ length: nv }, (_, k) => k);
const offU = [0, 2].map((a) => mode(all.map((k) => U(k) - su * pos[4 * k + a]), 1e-3)); // u from x, z
const offV = [1, 2].map((a) => mode(all.map((k) => V(k) + sv * pos[4 * k + a]), 1e-3)); // v from y, z
const tolerance = 3 * Math.max(su, sv) + 2e-4;
// plane of each vertex: 0 X (z, y), 1 Y (x, z), 2 Z (x, y)
const plane = all.map((k) => {
  const [x, y, z] = [0, 1, 2].map((c) => pos[4 * k + c]);
  const fits = (ua, uo, va, vo) =>
    Math.abs(U(k) - su * ua - offU[uo]) < tolerance && Math.abs(V(k) + sv * va - offV[vo]) < tolerance;
  if (fits(x, 0, y, 0)) return 2;
  if (fits(z, 1, y, 0)) return 0;
  if (fits(x, 0, z, 1)) return 1;
  throw new Error(`${file}: vertex ${k}'s texture coordinates are no box projection of its position`);
});

const vertexBytes = (a, stride, count, version) => E.encodeVertexBufferLevel(u8(a), count, stride, 2, version).length;
const normalBytes = (n, count, version) => {
  const f = Float32Array.from(n, (c) => Math.max(c / 127, -1));
  return E.encodeVertexBufferLevel(E.encodeFilterOct(f, count, 4, 8), count, 4, 2, version).length;
};
const indexBytes = (ix) => E.encodeIndexBuffer(u8(ix), ix.length, 4).length;

// streams of the vertices `order` (old numbers, new order), `w` the fourth position component
const measure = (order, w, lists, withTexcoord) => {
  const m = order.length;
  const gather = (src, T, n) => {
    const out = new T(n * m);
    order.forEach((v, i) => { for (let c = 0; c < n; c++) out[n * i + c] = src[n * v + c]; });
    return out;
  };
  const p = gather(pos, Int16Array, 4);
  if (w) order.forEach((v, i) => (p[4 * i + 3] = w(v)));
  const n = gather(nrm, Int8Array, 4), e = gather(ext, Int16Array, 4), t = gather(uvq, Uint16Array, 2);
  return [0, 1].map((version) => {
    const s = {
      position: vertexBytes(p, 8, m, version),
      normal: normalBytes(n, m, version),
      extrusion: vertexBytes(e, 8, m, version),
      texcoord: withTexcoord ? vertexBytes(t, 4, m, version) : 0,
      indices: lists.reduce((a, ix) => a + indexBytes(ix), 0),
    };
    return { vertices: m, ...s, total: Object.values(s).reduce((a, b) => a + b, 0) };
  });
};

const rows = [];
rows.push(['as written', measure(all, null, indices, true)]);
// planes apart: each plane's vertices together (a node per plane), permuted so that (x, y) holds
// its two coordinates, with normals and deltas permuted alike; each plane's triangles its own list
{
  const perm = [[1, 2, 0], [2, 0, 1], [0, 1, 2]]; // X stores (y, z, x); Y (z, x, y); Z as is
  const saved = [pos.slice(), nrm.slice(), ext.slice()];
  for (const a of [pos, nrm, ext]) {
    const src = a.slice();
    for (let k = 0; k < nv; k++) for (let c = 0; c < 3; c++) a[4 * k + c] = src[4 * k + perm[plane[k]][c]];
  }
  const order = [0, 1, 2].flatMap((p) => all.filter((k) => plane[k] === p));
  const local = new Int32Array(nv);
  for (const p of [0, 1, 2]) order.filter((k) => plane[k] === p).forEach((k, i) => (local[k] = i));
  const lists = indices.flatMap((ix) => [0, 1, 2].map((p) => {
    const out = [];
    for (let t = 0; t < ix.length; t += 3) if (plane[ix[t]] === p) out.push(local[ix[t]], local[ix[t + 1]], local[ix[t + 2]]);
    return Uint32Array.from(out);
  })).filter((ix) => ix.length > 0);
  rows.push(['texcoord from position, planes apart', measure(order, null, lists, false)]);
  [pos, nrm, ext].forEach((a, i) => a.set(saved[i]));
}
// shared: merge copies equal in every other stream, X and Y copies apart
{
  const key = (k) => [0, 1, 2].map((c) => `${pos[4 * k + c]},${nrm[4 * k + c]},${ext[4 * k + c]}`).join(';');
  const groups = new Map();
  for (const k of all) {
    const g = groups.get(key(k)) ?? [];
    g.push(k);
    groups.set(key(k), g);
  }
  const into = new Int32Array(nv);
  const wOf = new Int8Array(nv).fill(2);
  for (const g of groups.values()) {
    const x = g.find((k) => plane[k] === 0), y = g.find((k) => plane[k] === 1), z = g.find((k) => plane[k] === 2);
    for (const k of g) into[k] = plane[k] === 0 ? x : plane[k] === 1 ? y : x ?? y ?? z;
  }
  for (const k of all) if (plane[k] !== 2) wOf[into[k]] = plane[k];
  const w = (v) => (wOf[v] === 1 ? pos[4 * v] : pos[4 * v + 1]);
  // vertices in first use over `lists` (merged numbering), and the lists renumbered
  const renumber = (lists) => {
    const first = new Int32Array(nv).fill(-1), order = [];
    for (const ix of lists) for (const v of ix) if (first[v] < 0) (first[v] = order.length), order.push(v);
    return [order, lists.map((ix) => Uint32Array.from(ix, (v) => first[v]))];
  };
  // w of each vertex in `order`: y or x on the X or Y plane, else the w before it
  const carried = (order) => {
    const ws = new Map();
    let last = 0;
    for (const v of order) ws.set(v, wOf[v] === 2 ? last : (last = w(v)));
    return (v) => ws.get(v);
  };
  const merged = indices.map((ix) => Uint32Array.from(ix, (v) => into[v]));
  {
    const [order, lists] = renumber(merged);
    rows.push(['shared, streams kept whole (one primitive cannot read both offsets)', measure(order, carried(order), lists, false)]);
  }
  // a face is B's when it lies on the Z plane (its corners' copies are all Z copies)
  const onZ = (ix, t) => plane[ix[t]] === 2;
  const part = (b) => indices.map((ix, i) => {
    const out = [];
    for (let t = 0; t < ix.length; t += 3) if (onZ(ix, t) === b) out.push(merged[i][t], merged[i][t + 1], merged[i][t + 2]);
    return Uint32Array.from(out);
  });
  const [order, lists] = renumber([...part(false), ...part(true)]);
  rows.push(['texcoord from position, shared, two primitives', measure(order, carried(order), lists, false)]);
  // not a layout (the X or Y plane would have no coordinates): what the w column costs
  rows.push(['the same without w', measure(order, () => 0, lists, false)]);
}

const planes = [0, 1, 2].map((p) => plane.filter((q) => q === p).length);
console.log(`${file}: ${nv} vertices (planes X ${planes[0]}, Y ${planes[1]}, Z ${planes[2]}); compressed bytes of the`);
console.log('vertex and index streams (mask and JSON not included), vertex codec version 0 (EXT) / 1 (KHR):\n');
console.log('| layout | vertices | position | normal | extrusion | texcoord | indices | total |');
console.log('|---|---|---|---|---|---|---|---|');
for (const [name, [v0, v1]] of rows) {
  const cell = (k) => `${v0[k]} / ${v1[k]}`;
  console.log(`| ${name} | ${v0.vertices} | ${cell('position')} | ${cell('normal')} | ${cell('extrusion')} | ${cell('texcoord')} | ${v0.indices} | ${cell('total')} |`);
}
