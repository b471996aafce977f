// Renders GLB files with stock PlayCanvas in headless Chromium (WebGL 2 on SwiftShader) and
// writes PNGs: the file loaded as a PlayCanvas user loads one, nothing of shellbake's own.
// Usage: node playcanvas_render.mjs JOBS.json
// JOBS.json: three_render.mjs's jobs: [{ "glb": path, "png": path, "width": W, "height": H,
//               "camera": { "eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fovy_deg": f,
//                           "near": n, "far": f },
//               "light": { "direction": [x,y,z] (towards the light), "intensity": i },
//               "ambient": a, "background": [r,g,b] (linear),
//               "timeout_s": s (optional, default 120: the most one job may take),
//               "opacity_from_vertex_alpha": true (optional, NOT stock: what a PlayCanvas user must
//                       add before COLOR_0's alpha reaches the alpha test; see below) }, ...]
// The keys only three.js's page knows (`camera.auto`, `msft_lod`, `time`, `hide_fur`) are
// ignored. Light, ambient and background mean what they mean to three_render.mjs, and the page
// turns them into PlayCanvas's terms so that both engines light a surface alike: three.js's
// Lambert term is `albedo/π · irradiance`, PlayCanvas's `albedo · light`, so the directional
// light and the ambient are divided by π; PlayCanvas takes light and ambient colours in gamma
// space (`Color.linear`, a 2.2 power), so the linear values are handed over through
// `Color.gamma`; the clear colour is written to the canvas as given, so it is the background
// sRGB-encoded, as three.js writes it.
// The page: `app.assets.loadFromUrl(url, 'container', cb)`, then
// `asset.resource.instantiateRenderEntity()` added to the root (every scene of the file, as
// PlayCanvas instantiates them), a camera entity (vertical field of view, as the job's), a
// directional light; one frame drawn with preserveDrawingBuffer and read back once PlayCanvas has
// ended a frame that held the entity. One application serves consecutive jobs of one size (a
// fresh one per job spent most of its time compiling the same shaders again on SwiftShader): after
// each job its entity, camera and light are destroyed and its asset unloaded and removed, and the
// pictures are the same to the byte as with an application per job. A job that fails destroys
// the application; the next job makes a new one.
// `opacity_from_vertex_alpha` sets `opacityVertexColor` (channel `a`) on every material of the
// file before it is instantiated. glTF multiplies the base colour's alpha by COLOR_0's alpha
// before the alpha test; PlayCanvas's glb-parser (`createMaterial`) turns on
// `diffuseVertexColor` and `specularVertexColor` only (rgb), so stock PlayCanvas alpha-tests
// the texture's alpha alone. The key is a diagnosis, not how PlayCanvas loads a file.
// Prints one JSON line per job: { png, ok, meshInstances (mesh instances of the render components
// under the instantiated entity), drawCalls (PlayCanvas's count for the first of the two frames),
// error (when not ok) }; exits 1 if any job failed, with the errors on stderr.
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
<script type="importmap">{"imports":{"playcanvas":"/node_modules/playcanvas/build/playcanvas.mjs"}}</script>
<script type="module">
import * as pc from 'playcanvas';
const srgb = (v) => (v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055);
// A linear value as PlayCanvas's gamma-space colours take it (they are linearized with a 2.2 power).
const linear = (r, g, b) => new pc.Color(r, g, b).gamma();
const step = (what, promise, deadline) => Promise.race([promise, new Promise((_, fail) => {
  setTimeout(() => fail(new Error('timed out after ' + deadline.total / 1000 + ' s waiting for ' + what)),
    Math.max(0, deadline.at - performance.now()));
})]);
// The application of the jobs so far ({ app, canvas, width, height }), or null.
let kept = null;
const application = (job) => {
  if (kept && (kept.width !== job.width || kept.height !== job.height)) {
    kept.app.destroy();
    kept = null;
  }
  if (kept) return kept;
  const canvas = document.createElement('canvas');
  canvas.width = job.width; canvas.height = job.height;
  document.body.replaceChildren(canvas);
  const app = new pc.Application(canvas, {
    graphicsDeviceOptions: { antialias: false, preserveDrawingBuffer: true, alpha: false },
  });
  kept = { app, canvas, width: job.width, height: job.height };
  if (!app.graphicsDevice.isWebGL2) throw new Error('PlayCanvas did not get a WebGL 2 device');
  app.graphicsDevice.maxPixelRatio = 1;
  app.setCanvasFillMode(pc.FILLMODE_NONE, job.width, job.height);
  app.setCanvasResolution(pc.RESOLUTION_FIXED, job.width, job.height);
  app.start();
  return kept;
};
window.renderJob = async (job, url) => {
  const deadline = { total: (job.timeout_s ?? 120) * 1000 };
  deadline.at = performance.now() + deadline.total;
  // what this job added to the application, taken away after it
  const added = [];
  let asset = null;
  let failed = true;
  try {
    const { app, canvas } = application(job);
    asset = await step('the container asset to load', new Promise((done, fail) => {
      app.assets.loadFromUrl(url, 'container', (err, a) => (err ? fail(new Error('loading: ' + err)) : done(a)));
    }), deadline);
    if (job.opacity_from_vertex_alpha) {
      for (const m of asset.resource.materials) {
        m.resource.opacityVertexColor = true;
        m.resource.opacityVertexColorChannel = 'a';
        m.resource.update();
      }
    }
    const entity = asset.resource.instantiateRenderEntity();
    app.root.addChild(entity);
    added.push(entity);
    const meshInstances = entity.findComponents('render').reduce((n, r) => n + r.meshInstances.length, 0);

    const c = job.camera;
    if (c.auto) throw new Error('camera.auto is three_render.mjs only: give eye, target, up');
    const camera = new pc.Entity('camera');
    const bg = job.background.map(srgb);
    camera.addComponent('camera', {
      clearColor: new pc.Color(bg[0], bg[1], bg[2], 1),
      fov: c.fovy_deg, horizontalFov: false, nearClip: c.near, farClip: c.far,
      toneMapping: pc.TONEMAP_LINEAR, gammaCorrection: pc.GAMMA_SRGB,
    });
    camera.setPosition(...c.eye);
    camera.lookAt(new pc.Vec3(...c.target), new pc.Vec3(...c.up));
    app.root.addChild(camera);
    added.push(camera);

    // A directional light shines down its entity's -Y: turn +Y towards the light.
    const d = new pc.Vec3(...job.light.direction).normalize();
    const sun = new pc.Entity('sun');
    const i = job.light.intensity / Math.PI;
    sun.addComponent('light', { type: 'directional', color: linear(1, 1, 1), intensity: 1, castShadows: false });
    sun.light.color = linear(i, i, i);
    sun.setRotation(new pc.Quat().setFromDirections(pc.Vec3.UP, d));
    app.root.addChild(sun);
    added.push(sun);
    const y = sun.getWorldTransform().getY(new pc.Vec3()).normalize();
    if (y.distance(d) > 1e-4) throw new Error('light placed wrong: +Y ' + y + ' for ' + d);
    const a = job.ambient / Math.PI;
    app.scene.ambientLight = linear(a, a, a);

    // Read back after the second frame that ended with the entity in the scene: the first may
    // still have compiled shaders or uploaded textures on the way.
    const stats = await step('PlayCanvas to draw the frame', new Promise((done) => {
      let frames = 0;
      const onEnd = () => {
        if (++frames < 2) return;
        app.off('frameend', onEnd);
        done({ drawCalls: app.stats.drawCalls.total });
      };
      app.on('frameend', onEnd);
    }), deadline);
    const data = canvas.toDataURL('image/png');
    failed = false;
    return { data, meshInstances, ...stats };
  } finally {
    for (const e of added) e.destroy();
    if (asset) {
      const registry = asset.registry;
      asset.unload();
      registry?.remove(asset);
    }
    if (failed && kept) {
      kept.app.destroy();
      kept = null;
    }
  }
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
let failed = 0;
try {
  const page = await browser.newPage();
  const logs = [];
  page.on('console', (m) => logs.push(m.text()));
  page.on('pageerror', (e) => logs.push(String(e)));
  await page.goto(`http://127.0.0.1:${port}/`);
  await page.waitForFunction(() => window.ready === true, null, { timeout: 30000 }).catch((e) => {
    throw new Error(`the PlayCanvas page did not start: ${e.message}\n${logs.join('\n')}`);
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
      console.error(`playcanvas_render: ${error}`);
    }
  }
  if (logs.length) console.error(logs.join('\n'));
} finally {
  await browser.close();
  server.close();
}
process.exitCode = failed ? 1 : 0;
