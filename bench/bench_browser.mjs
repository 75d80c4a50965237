// The layered character in a browser, measured: headless Chromium plays
// Fox and CesiumMan rigs through three.js + Strata's plugin (the WebAssembly
// runtime) at levels 2 and 3, and three.js playing the detailed glb
// strata-reconstruct writes at the same level (the file a web user would
// otherwise ship), in one run, on one page:
//   bytes       what the page downloads for the model (the rig, or the
//               detailed glb; the WASM module is its own row)
//   load ms     GLTFLoader.loadAsync to a drawable scene (median of 3)
//   update ms   per frame on the CPU: AnimationMixer.update and the scene's
//               matrix update, which for the rig evaluates the surface in
//               WebAssembly (mean over the frames)
//   adaptive    the rig with setView(camera, 1 px on the 480-pixel view)
//               each frame: each control face at the lowest level within a
//               pixel of the row's level (drawn vertices: the mean frame's
//               own, without seam copies; update includes the choice)
//   frame ms    update + renderer.render + a one-pixel readPixels that waits
//               for the draw (mean): Chromium's WebGL2 on
//               SwiftShader (no GPU on these machines), so the draw is CPU
//               emulated and only comparable within this table
//
//   node bench/bench_browser.mjs [--build BUILD] [--frames 120] [--json]
// Needs js/node_modules (npm ci), js/dist (npm run build:wasm) and a build
// of the native tools.
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import zlib from 'node:zlib';
import { importMap, launchChromium, openPage, root, serve } from '../js/tools/browser.mjs';

const option = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i >= 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
};
const build = path.resolve(option('--build', path.join(root, 'build')));
const frames = Number(option('--frames', '120'));
const json = process.argv.includes('--json');
const work = fs.mkdtempSync(path.join(os.tmpdir(), 'strata-bench-browser-'));
const data = path.join(root, 'tests', 'data');

function run(tool, args) {
  const r = spawnSync(path.join(build, 'tools', tool), args, { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`${tool} ${args.join(' ')} failed:\n${r.stderr}`);
}

const characters = ['Fox', 'CesiumMan'];
const levels = [2, 3];
// Fox on 200 faces, as in this table's earlier runs: left to the search it
// takes its 576 triangles whole (level 0, nothing displaced).
for (const name of characters) {
  run('strata-bake', ['--high', path.join(data, `${name}.glb`), '--control', 'auto', '-o', path.join(work, `${name}.glb`)]
    .concat(name === 'Fox' ? ['--control-faces', '200'] : []));
  for (const level of levels)
    run('strata-reconstruct', [path.join(work, `${name}.glb`), '--level', String(level), '-o',
      path.join(work, `${name}_L${level}_detailed.glb`)]);
}

const page = `<!doctype html><html><body style="margin:0">
<script type="importmap">${importMap}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { StrataLoaderPlugin, StrataRuntime } from 'strata-layered/three';
const renderer = new THREE.WebGLRenderer({ antialias: false });
renderer.setSize(640, 480);
document.body.appendChild(renderer.domElement);
const gl = renderer.getContext();
const median = (a) => { const s = [...a].sort((x, y) => x - y); return s[s.length >> 1]; };
window.wasmLoad = async () => { const t0 = performance.now(); await StrataRuntime.load(); return performance.now() - t0; };
async function load(url, level) {
  const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
  if (level !== null) loader.register((parser) => new StrataLoaderPlugin(parser, { level }));
  return loader.loadAsync(url);
}
window.measure = async (url, level, frames, adaptive = false) => {
  const loads = [];
  let gltf;
  for (let i = 0; i < 3; ++i) {
    const t0 = performance.now();
    gltf = await load(url + '?' + i, level);
    loads.push(performance.now() - t0);
    if (i < 2 && gltf.userData.strata) gltf.userData.strata.dispose();
  }
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 2));
  scene.add(gltf.scene);
  const camera = new THREE.PerspectiveCamera(40, 640 / 480, 0.01, 1e4);
  const box = new THREE.Box3().setFromObject(gltf.scene);
  const c = box.getCenter(new THREE.Vector3());
  camera.position.copy(c).add(new THREE.Vector3(0, 0, 2.2 * box.getSize(new THREE.Vector3()).length()));
  camera.lookAt(c);
  const mixer = new THREE.AnimationMixer(gltf.scene);
  mixer.clipAction(gltf.animations[0]).play();
  let vertices = 0;
  gltf.scene.traverse((o) => { if (o.isMesh && o.visible) vertices += o.geometry.attributes.position.count; });
  // Timed as whole loops: the page's clock is coarse (0.1 ms).
  const pixel = new Uint8Array(4);
  const strata = gltf.userData.strata;
  let drawnSum = 0, drawnFrames = 0;
  const step = (draw) => {
    mixer.update(1 / 60);
    scene.updateMatrixWorld();
    if (adaptive) {
      drawnSum += strata.setView(camera, { pixelError: 1, heightPx: 480 }).vertices;
      drawnFrames++;
    }
    if (draw) {
      renderer.render(scene, camera);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);  // waits for the draw
    }
  };
  for (let f = 0; f < 10; ++f) step(true);
  let t0 = performance.now();
  for (let f = 0; f < frames; ++f) step(false);
  const update = (performance.now() - t0) / frames;
  t0 = performance.now();
  for (let f = 0; f < frames; ++f) step(true);
  const frame = (performance.now() - t0) / frames;
  if (adaptive) vertices = Math.round(drawnSum / drawnFrames);  // the frame's own vertices, mean
  if (gltf.userData.strata) gltf.userData.strata.dispose();
  return { load: median(loads), update, frame, vertices };
};
window.ready = true;
</script></body></html>`;

const server = await serve({ '/work/': work }, { '/bench.html': page });
const browser = await launchChromium();
const rows = [];
try {
  const tab = await openPage(browser, `${server.url}/bench.html`, { viewport: { width: 640, height: 480 } });
  await tab.waitForFunction('window.ready === true', { timeout: 60000 });
  const wasmMs = await tab.evaluate(() => window.wasmLoad());
  const wasm = fs.readFileSync(path.join(root, 'js', 'dist', 'strata.wasm'));
  const glue = fs.readFileSync(path.join(root, 'js', 'dist', 'strata.mjs'));
  const gz = (b) => zlib.gzipSync(b, { level: 9 }).length;
  rows.push({ mesh: 'strata.wasm + strata.mjs', mode: 'module', level: null, bytes: wasm.length + glue.length,
    gzip: gz(wasm) + gz(glue), load_ms: wasmMs });
  for (const name of characters)
    for (const level of levels) {
      const rigFile = path.join(work, `${name}.glb`);
      const detailed = path.join(work, `${name}_L${level}_detailed.glb`);
      const a = await tab.evaluate((u, l, n) => window.measure(u, l, n), `/work/${name}.glb`, level, frames);
      rows.push({ mesh: name, mode: 'strata rig', level, bytes: fs.statSync(rigFile).size,
        gzip: gz(fs.readFileSync(rigFile)), vertices: a.vertices, load_ms: a.load, update_ms: a.update, frame_ms: a.frame });
      const d = await tab.evaluate((u, l, n) => window.measure(u, l, n, true), `/work/${name}.glb`, level, frames);
      rows.push({ mesh: name, mode: 'strata rig, adaptive 1 px', level, bytes: fs.statSync(rigFile).size,
        gzip: gz(fs.readFileSync(rigFile)), vertices: d.vertices, load_ms: d.load, update_ms: d.update, frame_ms: d.frame });
      const b = await tab.evaluate((u, n) => window.measure(u, null, n), `/work/${name}_L${level}_detailed.glb`, frames);
      rows.push({ mesh: name, mode: 'detailed glb', level, bytes: fs.statSync(detailed).size,
        gzip: gz(fs.readFileSync(detailed)), vertices: b.vertices, load_ms: b.load, update_ms: b.update, frame_ms: b.frame });
    }
  if (tab.errors.length) throw new Error(tab.errors.join('\n'));
} finally {
  await browser.close();
  await server.close();
  fs.rmSync(work, { recursive: true, force: true });
}

if (json) {
  console.log(JSON.stringify(rows, null, 1));
} else {
  const version = spawnSync('/usr/bin/chromium', ['--version'], { encoding: 'utf8' }).stdout.trim();
  console.log(`${version}, WebGL2 on SwiftShader, ${os.cpus().length} cores, ${frames} frames at 60 Hz steps`);
  console.log('| model | what | level | bytes | gzip | drawn vertices | load ms | update ms | frame ms |');
  console.log('|---|---|---:|---:|---:|---:|---:|---:|---:|');
  const f = (x, d = 2) => (x === undefined || x === null ? '' : x.toFixed(d));
  for (const r of rows)
    console.log(`| ${r.mesh} | ${r.mode} | ${r.level ?? ''} | ${r.bytes.toLocaleString('en')} | ${r.gzip.toLocaleString('en')} | ` +
      `${r.vertices ? r.vertices.toLocaleString('en') : ''} | ${f(r.load_ms, 1)} | ${f(r.update_ms)} | ${f(r.frame_ms)} |`);
}
