// Renders GLB files with three.js in headless Chromium (WebGL on SwiftShader) and writes PNGs.
// Usage: node three_render.mjs JOBS.json
// JOBS.json: [{ "glb": path, "png": path, "width": W, "height": H,
//               "camera": { "eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fovy_deg": f,
//                           "near": n, "far": f }
//                      or { "auto": true, "yaw": deg, "pitch": deg, "distance": radii, "fovy_deg": f },
//               "light": { "direction": [x,y,z] (towards the light), "intensity": i },
//               "ambient": a, "background": [r,g,b] (linear),
//               "msft_lod": true (optional: switch MSFT_lod levels by distance),
//               "time": seconds (optional: every animation of the file played to that time by
//                       three.js's AnimationMixer, looping),
//               "hide_fur": true (optional: hide the nodes shellbake added to an asset, those
//                       whose extras carry `shellbake` or `shellbake_fur`) }, ...]
// Prints one JSON line per job: { png, ok, triangles and calls (drawn in the frame), bounds }. `bounds`:
// the world boxes three.js computes ({min, max} or null) of the fur shellbake added to an asset
// (`fur`, the meshes under a node whose extras carry `shellbake` or `shellbake_fur`) and of the
// rest (`bare`); a skinned mesh's box is its skinned vertices' (SkinnedMesh.computeBoundingBox).
// Files are served from a loopback HTTP server; Chromium is Debian's, driven by playwright-core.
import { createServer } from 'node:http';
import { readFile, writeFile } from 'node:fs/promises';
import { dirname, join, resolve, extname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const jobs = JSON.parse(await readFile(process.argv[2], 'utf8'));
const files = new Map(jobs.map((j, i) => [`/asset/${i}.glb`, resolve(j.glb)]));
const types = { '.js': 'text/javascript', '.mjs': 'text/javascript', '.html': 'text/html', '.glb': 'model/gltf-binary' };

const page_html = `<!doctype html><html><body style="margin:0">
<script type="importmap">{"imports":{"three":"/node_modules/three/build/three.module.js","three/addons/":"/node_modules/three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
// MSFT_lod, written here (three.js's GLTFLoader does not read it): each node with the extension
// becomes a THREE.LOD placed at the centre of its LOD 0 content (or at extras.shellbake_lod.centre
// where the file states one: a skinned fur's layer nodes each carry the chain, from one centre,
// so they switch as one), with the coarser levels' nodes as further levels at the switch
// distances of extras.shellbake_lod (world units). A skinned mesh ignores its parents'
// transforms (three.js's attached bind mode), so it can sit under the LOD as it is.
// Nodes are looked up with parser.getDependency, not parser.associations: GLTFLoader keeps the
// associations of the last scene it loads only, and the coarser levels are a scene of their own.
class MsftLod {
  constructor(parser) { this.parser = parser; this.name = 'MSFT_lod'; }
  async afterRoot(result) {
    const parser = this.parser;
    result.scene.updateMatrixWorld(true);
    for (const [i, node] of (parser.json.nodes || []).entries()) {
      const ext = node.extensions && node.extensions.MSFT_lod;
      const figures = node.extras && node.extras.shellbake_lod;
      const distances = figures && figures.distances;
      if (!ext || !distances) continue;
      const obj = await parser.getDependency('node', i);
      if (!obj.parent) continue;
      const parent = obj.parent;
      const world = figures.centre ? new THREE.Vector3(...figures.centre)
        : new THREE.Box3().setFromObject(obj).getCenter(new THREE.Vector3());
      const centre = parent.worldToLocal(world);
      const lod = new THREE.LOD();
      lod.name = obj.name;
      lod.position.copy(centre);
      parent.add(lod);
      parent.remove(obj);
      const levels = [obj];
      for (const id of ext.ids) levels.push((await parser.getDependency('node', id)).clone());
      levels.forEach((o, k) => { o.position.sub(centre); lod.addLevel(o, distances[k]); });
    }
  }
}
window.renderJob = async (job, url) => {
  const canvas = document.createElement('canvas');
  canvas.width = job.width; canvas.height = job.height;
  document.body.replaceChildren(canvas);
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(job.width, job.height, false);
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  renderer.toneMapping = THREE.NoToneMapping;
  const scene = new THREE.Scene();
  scene.background = new THREE.Color().setRGB(...job.background, THREE.LinearSRGBColorSpace);
  const loader = new GLTFLoader();
  loader.setMeshoptDecoder(MeshoptDecoder);
  if (job.msft_lod) loader.register((parser) => new MsftLod(parser));
  const gltf = await loader.loadAsync(url);
  scene.add(gltf.scene);
  if (job.hide_fur) {
    gltf.scene.traverse((o) => {
      if (o.userData.shellbake !== undefined || o.userData.shellbake_fur !== undefined) o.visible = false;
    });
  }
  if (job.time !== undefined && gltf.animations.length) {
    const mixer = new THREE.AnimationMixer(gltf.scene);
    for (const clip of gltf.animations) mixer.clipAction(clip).play();
    mixer.setTime(job.time);
  }
  let c = job.camera;
  if (c.auto) {
    // Frame the bounding sphere from yaw/pitch (degrees) at c.distance radii.
    const sphere = new THREE.Box3().setFromObject(gltf.scene).getBoundingSphere(new THREE.Sphere());
    const yaw = THREE.MathUtils.degToRad(c.yaw), pitch = THREE.MathUtils.degToRad(c.pitch);
    const dir = [Math.sin(yaw) * Math.cos(pitch), Math.sin(pitch), Math.cos(yaw) * Math.cos(pitch)];
    const d = sphere.radius * c.distance;
    const t = sphere.center.toArray();
    c = { eye: t.map((v, i) => v + dir[i] * d), target: t, up: [0, 1, 0], fovy_deg: c.fovy_deg,
          near: d / 100, far: d * 4 };
  }
  const camera = new THREE.PerspectiveCamera(c.fovy_deg, job.width / job.height, c.near, c.far);
  camera.position.set(...c.eye); camera.up.set(...c.up); camera.lookAt(...c.target);
  const sun = new THREE.DirectionalLight(0xffffff, job.light.intensity);
  sun.position.set(...job.light.direction); sun.target.position.set(0, 0, 0);
  scene.add(sun); scene.add(sun.target);
  scene.add(new THREE.AmbientLight(0xffffff, job.ambient));
  renderer.render(scene, camera);
  const data = canvas.toDataURL('image/png');
  const triangles = renderer.info.render.triangles;
  const calls = renderer.info.render.calls;
  renderer.dispose();
  const isFur = (o) => {
    for (let n = o; n; n = n.parent) {
      if (n.userData.shellbake !== undefined || n.userData.shellbake_fur !== undefined) return true;
    }
    return false;
  };
  const boxes = { fur: new THREE.Box3(), bare: new THREE.Box3() };
  gltf.scene.updateMatrixWorld(true);
  gltf.scene.traverse((o) => {
    if (!o.isMesh) return;
    o.computeBoundingBox ? o.computeBoundingBox() : o.geometry.computeBoundingBox();
    const box = (o.isSkinnedMesh ? o.boundingBox : o.geometry.boundingBox).clone();
    box.applyMatrix4(o.matrixWorld);
    boxes[isFur(o) ? 'fur' : 'bare'].union(box);
  });
  const json = (b) => (b.isEmpty() ? null : { min: b.min.toArray(), max: b.max.toArray() });
  return { data, triangles, calls, bounds: { fur: json(boxes.fur), bare: json(boxes.bare) } };
};
window.ready = true;
</script></body></html>`;

const server = createServer(async (req, res) => {
  try {
    const url = new URL(req.url, 'http://127.0.0.1');
    let path;
    if (url.pathname === '/') {
      res.writeHead(200, { 'content-type': 'text/html' });
      return res.end(page_html);
    } else if (files.has(url.pathname)) {
      path = files.get(url.pathname);
    } else if (url.pathname.startsWith('/node_modules/')) {
      path = join(here, url.pathname);
      if (!path.startsWith(join(here, 'node_modules'))) throw new Error('outside');
    } else {
      throw new Error('not found');
    }
    const body = await readFile(path);
    res.writeHead(200, { 'content-type': types[extname(path)] || 'application/octet-stream' });
    res.end(body);
  } catch (e) {
    res.writeHead(404); res.end(String(e));
  }
});
await new Promise((r) => server.listen(0, '127.0.0.1', r));
const port = server.address().port;

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
try {
  const page = await browser.newPage();
  const logs = [];
  page.on('console', (m) => logs.push(m.text()));
  page.on('pageerror', (e) => logs.push(String(e)));
  await page.goto(`http://127.0.0.1:${port}/`);
  await page.waitForFunction(() => window.ready === true, null, { timeout: 30000 });
  for (const [i, job] of jobs.entries()) {
    const { data, triangles, calls, bounds } = await page.evaluate(([j, u]) => window.renderJob(j, u), [job, `/asset/${i}.glb`]);
    await writeFile(job.png, Buffer.from(data.split(',')[1], 'base64'));
    console.log(JSON.stringify({ png: job.png, ok: true, triangles, calls, bounds }));
  }
  if (logs.length) console.error(logs.join('\n'));
} finally {
  await browser.close();
  server.close();
}
