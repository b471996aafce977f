// Renders GLB files with stock Filament (npm `filament`: its WebAssembly build and gltfio) in
// headless Chromium (WebGL 2 on SwiftShader) and writes PNGs: the file loaded as a Filament web
// app loads one, nothing of shellbake's own.
// Usage: node filament_render.mjs JOBS.json
// JOBS.json: three_render.mjs's jobs: [{ "glb": path, "png": path, "width": W, "height": H,
//               "camera": { "eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fovy_deg": f,
//                           "near": n, "far": f },
//               "light": { "direction": [x,y,z] (towards the light), "intensity": i },
//               "ambient": a, "background": [r,g,b] (linear),
//               "scene": n (optional: add only the entities of glTF scene n, see below),
//               "timeout_s": s (optional, default 120: the most one job may take) }, ...]
// The keys only three.js's page knows (`camera.auto`, `msft_lod`, `time`, `hide_fur`) are
// ignored. Light, ambient and background mean what they mean to three_render.mjs, and the page
// turns them into Filament's terms so that both engines light a surface alike: Filament's
// Lambert term is `albedo/π · illuminance · exposure`, as three.js's is `albedo/π · irradiance`,
// so the directional light keeps its intensity (lux, the camera's exposure set to exactly 1);
// three.js's ambient term is `albedo/π · ambient`, Filament's indirect light `albedo · SH`
// (Filament's irradiance SH have Lambert's 1/π folded in), so the ambient is an `IndirectLight`
// of one SH band holding ambient/π at intensity 1; the tone mapping is LINEAR (Filament's default
// is an ACES curve) and FXAA (on by default) is off; the clear
// colour is given linear, as Filament takes it, and comes out sRGB-encoded as three.js writes it.
// The page: `Filament.init`, `Engine.create(canvas, {preserveDrawingBuffer})`,
// `engine.createAssetLoader().createAsset(bytes)`, `asset.loadResources(onDone)` (a GLB: the
// buffers are in the file, the PNG textures decoded by gltfio), then the entities added to the
// scene: `asset.getSceneEntities(0)` where the API has it, else `asset.getEntities()` (Filament
// 1.53.4's JavaScript API has no getSceneEntities: its getEntities holds every node of every glTF
// scene, so a file's second scene is drawn too). Each job reports which call it used
// (`entities_call`). With "scene": n the page instead keeps the entities whose glTF node is
// reached from scenes[n] (matched by node name, read from the file's JSON; names must be unique),
// what getSceneEntities(n) would add. A directional light, the camera (vertical field of view),
// then `renderer.render(swapChain, view)` once per animation frame until two frames in a row
// differ by at most 2 levels in every pixel (Filament's temporal dithering, which its JavaScript
// API cannot switch off, moves pixels by that much; textures and shaders are then in place), and
// the canvas read back (`toDataURL`, the context made with preserveDrawingBuffer).
// Prints one JSON line per job: { png, ok, entities_call, entities (added to the scene),
// all_entities (asset.getEntities()), renderables (scene.getRenderableCount(), the light
// excluded), frames (drawn before the picture held still), frame_change (the largest channel
// difference between the last two), error (when not ok) }; exits 1 if any job failed, with the
// errors on stderr.
// Files are served from a loopback HTTP server; Chromium is Debian's, driven by playwright-core.
import { createServer } from 'node:http';
import { readFile, writeFile } from 'node:fs/promises';
import { dirname, join, resolve, extname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const jobs = JSON.parse(await readFile(process.argv[2], 'utf8'));
const files = new Map(jobs.map((j, i) => [`/asset/${i}.glb`, resolve(j.glb)]));
const types = {
  '.js': 'text/javascript', '.mjs': 'text/javascript', '.html': 'text/html',
  '.glb': 'model/gltf-binary', '.wasm': 'application/wasm',
};

const page_html = `<!doctype html><html><body style="margin:0">
<script src="/node_modules/filament/filament.js"></script>
<script>
const step = (what, promise, deadline) => Promise.race([promise, new Promise((_, fail) => {
  setTimeout(() => fail(new Error('timed out after ' + deadline.total / 1000 + ' s waiting for ' + what)),
    Math.max(0, deadline.at - performance.now()));
})]);
// The names of the nodes scenes[index] reaches, from the GLB's JSON chunk.
const sceneNodeNames = (bytes, index) => {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const length = view.getUint32(12, true);
  const gltf = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + length)));
  const names = new Set();
  const stack = [...gltf.scenes[index].nodes];
  while (stack.length) {
    const node = gltf.nodes[stack.pop()];
    if (node.name === undefined || names.has(node.name)) throw new Error('scene filter needs unique node names');
    names.add(node.name);
    stack.push(...(node.children || []));
  }
  const all = gltf.nodes.map((n) => n.name);
  if (new Set(all).size !== all.length) throw new Error('scene filter needs unique node names');
  return names;
};
const nextFrame = () => new Promise((r) => requestAnimationFrame(r));
window.renderJob = async (job, url) => {
  const deadline = { total: (job.timeout_s ?? 120) * 1000 };
  deadline.at = performance.now() + deadline.total;
  const canvas = document.createElement('canvas');
  canvas.width = job.width; canvas.height = job.height;
  document.body.replaceChildren(canvas);
  let engine;
  try {
    engine = Filament.Engine.create(canvas, { preserveDrawingBuffer: true, antialias: false, alpha: false });
  } catch (e) {
    throw new Error('Filament could not start on a WebGL 2 context: ' + e.message);
  }
  let loader = null, asset = null;
  try {
    const scene = engine.createScene();
    const view = engine.createView();
    const renderer = engine.createRenderer();
    const swapChain = engine.createSwapChain();
    const cameraEntity = Filament.EntityManager.get().create();
    const camera = engine.createCamera(cameraEntity);
    view.setCamera(camera);
    view.setScene(scene);
    view.setViewport([0, 0, job.width, job.height]);
    view.setAntiAliasing(Filament.View$AntiAliasing.NONE);
    view.setColorGrading(Filament.ColorGrading.Builder()
      .toneMapping(Filament.ColorGrading$ToneMapping.LINEAR)
      .build(engine));
    renderer.setClearOptions({ clearColor: [...job.background, 1], clear: true });

    const bytes = new Uint8Array(await step('the file to download',
      fetch(url).then((r) => { if (!r.ok) throw new Error('fetching ' + url + ': ' + r.status); return r.arrayBuffer(); }),
      deadline));
    loader = engine.createAssetLoader();
    asset = loader.createAsset(bytes);
    if (!asset) throw new Error('gltfio refused the file (createAsset returned null)');
    await step('gltfio to load the resources', new Promise((done) => asset.loadResources(done, null, null, 1)), deadline);

    const all = asset.getEntities();
    let entities, entitiesCall;
    if (job.scene !== undefined) {
      const names = sceneNodeNames(bytes, job.scene);
      entities = all.filter((e) => names.has(asset.getName(e)));
      entitiesCall = 'getEntities() filtered to scenes[' + job.scene + '] by node name';
    } else if (typeof asset.getSceneEntities === 'function') {
      entities = asset.getSceneEntities(0);
      entitiesCall = 'getSceneEntities(0)';
    } else {
      entities = all;
      entitiesCall = 'getEntities()';
    }
    scene.addEntities(entities);

    const c = job.camera;
    if (c.auto) throw new Error('camera.auto is three_render.mjs only: give eye, target, up');
    camera.setProjectionFov(c.fovy_deg, job.width / job.height, c.near, c.far, Filament.Camera$Fov.VERTICAL);
    camera.lookAt(c.eye, c.target, c.up);
    camera.setExposureDirect(1.0);

    // Filament's direction is the way the light travels: away from the light.
    const d = job.light.direction;
    const n = Math.hypot(...d);
    const sun = Filament.EntityManager.get().create();
    Filament.LightManager.Builder(Filament.LightManager$Type.DIRECTIONAL)
      .color([1, 1, 1])
      .intensity(job.light.intensity)
      .direction(d.map((v) => -v / n))
      .castShadows(false)
      .build(engine, sun);
    scene.addEntity(sun);
    const a = job.ambient / Math.PI;
    const ibl = Filament.IndirectLight.Builder().irradianceSh(1, [a, a, a]).intensity(1.0).build(engine);
    scene.setIndirectLight(ibl);

    // Draw one frame per animation frame until two in a row differ by at most DITHER levels in
    // every pixel (at least 2 frames): Filament's temporal dithering, which the JavaScript API
    // cannot switch off, moves pixels by up to 2 levels from frame to frame; anything larger is
    // a texture or a shader still on its way.
    const DITHER = 2;
    const scratch = document.createElement('canvas');
    scratch.width = job.width; scratch.height = job.height;
    const ctx = scratch.getContext('2d', { willReadFrequently: true });
    const pixels = () => {
      ctx.drawImage(canvas, 0, 0);
      return ctx.getImageData(0, 0, job.width, job.height).data;
    };
    let previous = null, data = null, frames = 0, change = Infinity;
    while (frames < 2 || change > DITHER) {
      await step('Filament to draw a steady frame', nextFrame(), deadline);
      renderer.render(swapChain, view);
      frames += 1;
      const px = pixels();
      if (previous) {
        change = 0;
        for (let i = 0; i < px.length; i++) {
          if ((i & 3) !== 3) change = Math.max(change, Math.abs(px[i] - previous[i]));
        }
      }
      previous = px;
      data = canvas.toDataURL('image/png');
    }
    return {
      data, frames, frame_change: change, entities_call: entitiesCall, entities: entities.length, all_entities: all.length,
      renderables: scene.getRenderableCount(),
    };
  } finally {
    if (asset) loader.destroyAsset(asset);
    if (loader) loader.delete();
    Filament.Engine.destroy(engine);
  }
};
Filament.init([], () => { window.ready = true; });
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
let failed = 0;
try {
  const page = await browser.newPage();
  const logs = [];
  page.on('console', (m) => logs.push(m.text()));
  page.on('pageerror', (e) => logs.push(String(e)));
  await page.goto(`http://127.0.0.1:${port}/`);
  await page.waitForFunction(() => window.ready === true, null, { timeout: 60000 }).catch((e) => {
    throw new Error(`the Filament page did not start: ${e.message}\n${logs.join('\n')}`);
  });
  for (const [i, job] of jobs.entries()) {
    try {
      const { data, ...info } = await page.evaluate(([j, u]) => window.renderJob(j, u), [job, `/asset/${i}.glb`]);
      await writeFile(job.png, Buffer.from(data.split(',')[1], 'base64'));
      console.log(JSON.stringify({ png: job.png, ok: true, ...info }));
    } catch (e) {
      failed += 1;
      const error = `${job.glb}: ${e.message.split('\n')[0]}`;
      console.log(JSON.stringify({ png: job.png, ok: false, error }));
      console.error(`filament_render: ${error}`);
    }
  }
  if (logs.length) console.error(logs.join('\n'));
} finally {
  await browser.close();
  server.close();
}
process.exitCode = failed ? 1 : 0;
