// A layered character in three.js, as a web page loads it: Chromium
// (headless, through puppeteer-core) runs three's GLTFLoader on the source
// and on the rig strata-bake --control auto made of it, plays the first
// animation to its middle, and compares.  The rig must load with a skinned
// mesh, every animation and (where the source has one) a textured material
// whose image decoded, and stand, posed, within 3% of the source's box.
//
//   node js/tools/threejs-character.mjs --build BUILD_DIR [--work DIR]
//
// three and puppeteer-core come from js/node_modules (npm ci), Chromium
// from Debian (cmake/install-deps.sh).
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { chromiumPath, importMap, launchChromium, openPage, root, serve } from './browser.mjs';

const option = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i >= 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
};
const build = path.resolve(option('--build', path.join(root, 'build')));
// Without --work, a folder of its own, removed on exit (a default made
// eagerly left an empty one behind on every run that passed --work).
const given = option('--work', '');
const work = given ? path.resolve(given) : fs.mkdtempSync(path.join(os.tmpdir(), 'strata-threejs-'));
if (!given) process.on('exit', () => fs.rmSync(work, { recursive: true, force: true }));
fs.mkdirSync(work, { recursive: true });

try {
  chromiumPath();
} catch (e) {
  console.error(e.message);
  process.exit(1);
}

// Fox, CesiumMan, and rigid parts their nodes animate, no skin (made by
// tests/tools/rigid_parts_capture.py).
const characters = ['Fox', 'CesiumMan', 'rigid_parts'];
const made = spawnSync('python3', [path.join(root, 'tests', 'tools', 'rigid_parts_capture.py'),
  path.join(work, 'rigid_parts_source.glb')], { encoding: 'utf8' });
if (made.status !== 0) {
  console.error(`tests/tools/rigid_parts_capture.py failed:\n${made.stderr}`);
  process.exit(1);
}
for (const name of characters) {
  const source = name === 'rigid_parts' ? path.join(work, 'rigid_parts_source.glb')
    : path.join(root, 'tests', 'data', `${name}.glb`);
  const r = spawnSync(path.join(build, 'tools', 'strata-bake'),
    ['--high', source, '--control', 'auto', '-o', path.join(work, `${name}.glb`)], { encoding: 'utf8' });
  if (r.status !== 0) {
    console.error(`strata-bake ${name} failed:\n${r.stderr}`);
    process.exit(1);
  }
  if (name !== 'rigid_parts')
    fs.copyFileSync(source, path.join(work, `${name}_source.glb`));
}

const page = `<!doctype html><html><body>
<script type="importmap">${importMap}</script>
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

const server = await serve({ '/work/': work }, { '/': page });
const browser = await launchChromium();
let failed = 0;
try {
  const tab = await openPage(browser, `${server.url}/`);
  await tab.waitForFunction('window.ready === true', { timeout: 60000 });
  for (const name of characters) {
    const source = await tab.evaluate((u) => window.inspect(u), `/work/${name}_source.glb`);
    const rig = await tab.evaluate((u) => window.inspect(u), `/work/${name}.glb`);
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
      console.log(`${name}: plays in three.js: ${rig.skinned} skinned mesh, ${rig.animations} animations, ` +
        `${source.textured ? 'texture decoded, ' : ''}` +
        `posed at ${rig.time.toFixed(2)} s within ${(100 * off).toFixed(2)}% of the source's box`);
    }
  }
  for (const e of tab.errors) {
    ++failed;
    console.log(e);
  }
} finally {
  await browser.close();
  await server.close();
}
process.exit(failed ? 1 : 0);
