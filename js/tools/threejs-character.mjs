// A layered character in three.js, as a web page loads it: Chromium
// (headless, through puppeteer-core) runs three's GLTFLoader on the source
// and on the rig strata-bake --control auto made of it, plays the first
// animation to its middle, and compares.  The rig must load with a skinned
// mesh, every animation and a textured material whose image decoded, and
// stand, posed, within 3% of the source's box.
//
//   node js/tools/threejs-character.mjs --build BUILD_DIR [--work DIR]
//
// three and puppeteer-core come from js/node_modules (npm ci), Chromium
// from Debian (cmake/install-deps.sh).
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import puppeteer from 'puppeteer-core';

const here = path.dirname(fileURLToPath(import.meta.url));
const jsDir = path.resolve(here, '..');
const root = path.resolve(jsDir, '..');
const option = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i >= 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
};
const build = path.resolve(option('--build', path.join(root, 'build')));
const work = path.resolve(option('--work', fs.mkdtempSync(path.join(os.tmpdir(), 'strata-threejs-'))));
fs.mkdirSync(work, { recursive: true });

const chromium = ['/usr/bin/chromium', '/usr/bin/chromium-browser', '/usr/bin/google-chrome']
  .find((p) => fs.existsSync(p));
if (!chromium) {
  console.error('no Chromium (cmake/install-deps.sh installs Debian\'s chromium)');
  process.exit(1);
}

const characters = ['Fox', 'CesiumMan'];
for (const name of characters) {
  const r = spawnSync(path.join(build, 'tools', 'strata-bake'),
    ['--high', path.join(root, 'tests', 'data', `${name}.glb`), '--control', 'auto', '-o', path.join(work, `${name}.glb`)],
    { encoding: 'utf8' });
  if (r.status !== 0) {
    console.error(`strata-bake ${name} failed:\n${r.stderr}`);
    process.exit(1);
  }
  fs.copyFileSync(path.join(root, 'tests', 'data', `${name}.glb`), path.join(work, `${name}_source.glb`));
}

const page = `<!doctype html><html><body>
<script type="importmap">{"imports": {"three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
window.inspect = async (url) => {
  const gltf = await new GLTFLoader().loadAsync(url);
  const scene = gltf.scene;
  let skinned = 0, textured = 0, decoded = 0;
  scene.traverse((o) => {
    if (o.isSkinnedMesh) ++skinned;
    if (o.isMesh && o.material && o.material.map) {
      ++textured;
      const im = o.material.map.image;
      if (im && im.width > 0) ++decoded;
    }
  });
  const mixer = new THREE.AnimationMixer(scene);
  let time = null;
  if (gltf.animations.length) {
    const clip = gltf.animations[0];
    mixer.clipAction(clip).play();
    time = 0.5 * clip.duration;
    mixer.setTime(time);
  }
  scene.updateMatrixWorld(true);
  const box = new THREE.Box3();
  scene.traverse((o) => {
    if (o.isSkinnedMesh) {
      o.skeleton.update();
      o.computeBoundingBox();  // with the bones' pose
      box.union(o.boundingBox.clone().applyMatrix4(o.matrixWorld));
    } else if (o.isMesh) {
      box.expandByObject(o, true);
    }
  });
  return { skinned, animations: gltf.animations.length, textured, decoded, time,
           min: box.min.toArray(), max: box.max.toArray() };
};
window.ready = true;
</script></body></html>`;

const types = { '.js': 'text/javascript', '.glb': 'model/gltf-binary', '.html': 'text/html' };
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  if (url === '/') {
    res.writeHead(200, { 'content-type': 'text/html' });
    res.end(page);
    return;
  }
  const file = url.startsWith('/three/') ? path.join(jsDir, 'node_modules', 'three', url.slice('/three/'.length))
                                         : path.join(work, path.basename(url));
  if (!fs.existsSync(file)) {
    res.writeHead(404);
    res.end();
    return;
  }
  res.writeHead(200, { 'content-type': types[path.extname(file)] || 'application/octet-stream' });
  fs.createReadStream(file).pipe(res);
});
await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
const base = `http://127.0.0.1:${server.address().port}`;

const browser = await puppeteer.launch({ executablePath: chromium, headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'] });
let failed = 0;
try {
  const tab = await browser.newPage();
  tab.on('pageerror', (e) => console.error(`page error: ${e.message}`));
  await tab.goto(base + '/');
  await tab.waitForFunction('window.ready === true', { timeout: 60000 });
  for (const name of characters) {
    const source = await tab.evaluate((u) => window.inspect(u), `/${name}_source.glb`);
    const rig = await tab.evaluate((u) => window.inspect(u), `/${name}.glb`);
    const diag = Math.hypot(...source.max.map((v, k) => v - source.min[k]));
    const off = Math.max(Math.hypot(...rig.min.map((v, k) => v - source.min[k])),
      Math.hypot(...rig.max.map((v, k) => v - source.max[k]))) / diag;
    const problems = [];
    if (rig.skinned < 1) problems.push('no skinned mesh');
    if (rig.animations !== source.animations) problems.push(`${rig.animations} animations, the source has ${source.animations}`);
    if (source.textured && !rig.decoded) problems.push('no decoded texture');
    if (!(off <= 0.03)) problems.push(`posed at ${rig.time} s its box is ${(100 * off).toFixed(2)}% of the diagonal from the source's`);
    if (problems.length) {
      ++failed;
      console.log(`${name}: FAILED: ${problems.join('; ')}`);
    } else {
      console.log(`${name}: plays in three.js: ${rig.skinned} skinned mesh, ${rig.animations} animations, texture decoded, ` +
        `posed at ${rig.time.toFixed(2)} s within ${(100 * off).toFixed(2)}% of the source's box`);
    }
  }
} finally {
  await browser.close();
  server.close();
}
process.exit(failed ? 1 : 0);
