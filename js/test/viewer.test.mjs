// The web viewer in headless Chromium (WebGL2 on SwiftShader): it opens a
// rig from ?rig=, draws it (the canvas is not blank), changes level, shows
// the cage, wireframe and false colour, plays an animation (adaptively too),
// and names the cause when a file is refused.  STRATA_SCREENSHOTS=DIR saves its
// screenshots there (docs/images holds the ones the README shows).
import assert from 'node:assert/strict';
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { after, before, test } from 'node:test';
import { launchChromium, openPage, root, serve } from '../tools/browser.mjs';

const build = path.resolve(process.env.STRATA_BUILD_DIR || path.join(root, 'build'));
const work = fs.mkdtempSync(path.join(os.tmpdir(), 'strata-viewer-'));
const data = path.join(root, 'tests', 'data');
const shots = process.env.STRATA_SCREENSHOTS ? path.resolve(process.env.STRATA_SCREENSHOTS) : null;

function bake(args) {
  const r = spawnSync(path.join(build, 'tools', 'strata-bake'), args, { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`strata-bake ${args.join(' ')} failed:\n${r.stderr}`);
}

let server, browser;
before(async () => {
  bake(['--high', path.join(data, 'spot_triangulated.obj'), '--control', path.join(data, 'spot_control_mesh.obj'),
    '-o', path.join(work, 'spot.glb')]);
  // 1,000 faces, at level 1: the default search meets the tolerance in
  // every pose on 2,000 faces at level 0, which leaves adaptive nothing.
  bake(['--high', path.join(data, 'CesiumMan.glb'), '--control', 'auto', '--control-faces', '1000', '-o',
    path.join(work, 'CesiumMan.glb')]);
  fs.writeFileSync(path.join(work, 'broken.glb'), 'glTF this is not a rig');
  server = await serve({ '/work/': work });
  browser = await launchChromium();
});
after(async () => {
  if (browser) await browser.close();
  if (server) await server.close();
  fs.rmSync(work, { recursive: true, force: true });
});

async function open(rig) {
  const tab = await openPage(browser, `${server.url}/js/viewer/index.html?rig=/work/${rig}`);
  await tab.waitForFunction('window.strataViewer && window.strataViewer.ready === true', { timeout: 120000 });
  return tab;
}

// Distinct colours in the canvas: a blank or single-colour frame has one or two.
async function colours(tab) {
  return tab.evaluate(() => {
    const c = document.querySelector('canvas');
    const g = document.createElement('canvas');
    g.width = 96; g.height = 72;
    const ctx = g.getContext('2d');
    ctx.drawImage(c, 0, 0, g.width, g.height);
    const d = ctx.getImageData(0, 0, g.width, g.height).data;
    const seen = new Set();
    for (let i = 0; i < d.length; i += 4) seen.add((d[i] >> 3) << 10 | (d[i + 1] >> 3) << 5 | (d[i + 2] >> 3));
    return seen.size;
  });
}

async function shot(tab, name) {
  await new Promise((r) => setTimeout(r, 300));
  if (shots) {
    fs.mkdirSync(shots, { recursive: true });
    await tab.screenshot({ path: path.join(shots, name) });
  }
}

// The last frame is drawn (more than `least` colours), saved, and nothing
// went wrong on the page.
async function finish(tab, least, name) {
  assert.ok(await colours(tab) > least, 'the canvas is blank');
  await shot(tab, name);
  assert.deepEqual(tab.errors, []);
  await tab.close();
}

test('the viewer draws a rig, changes level and shows its layers', async () => {
  const tab = await open('spot.glb');
  assert.equal(await tab.evaluate(() => window.strataViewer.error || ''), '');
  const info = await tab.evaluate(() => ({ level: window.strataViewer.surface.level, stats: document.getElementById('stats').textContent }));
  assert.equal(info.level, 3);
  assert.match(info.stats, /level 3 \(recommended 3\): 11906 vertices/);
  assert.match(info.stats, /deviation from level 4/);
  assert.ok(await colours(tab) > 20, 'the canvas is blank');
  await shot(tab, 'web-viewer-spot.png');
  const level = await tab.evaluate(() => {
    const s = document.getElementById('level');
    s.value = '1';
    s.dispatchEvent(new Event('input'));
    return window.strataViewer.surface.refinedVertexCount;
  });
  assert.equal(level, 188 + 558);  // level 1 of a closed 188-vertex, 372-triangle cage: V + E
  await tab.evaluate(() => {
    const s = document.getElementById('level');
    s.value = '3';
    s.dispatchEvent(new Event('input'));
    document.getElementById('falseColour').click();
    document.getElementById('cage').click();
  });
  await finish(tab, 20, 'web-viewer-false-colour.png');
});

test('the viewer plays a character', async () => {
  const tab = await open('CesiumMan.glb');
  assert.equal(await tab.evaluate(() => window.strataViewer.error || ''), '');
  // Each step waits for the page to show its effect rather than for a fixed
  // time: under load (a busy CI machine) SwiftShader draws a frame a second.
  const moved = await tab.evaluate(async () => {
    const a = window.strataViewer.surface.geometry.attributes.position.array.slice(0, 300);
    for (let t = 0; t < 200; ++t) {
      await new Promise((r) => setTimeout(r, 100));
      const b = window.strataViewer.surface.geometry.attributes.position.array;
      if (a.some((x, i) => x !== b[i])) return true;
    }
    return false;
  });
  assert.ok(moved, 'the animation does not move the surface in 20 s');
  // Adaptive: fewer vertices than the level everywhere, said in the stats;
  // a looser tolerance draws fewer still; off again, the level everywhere.
  const adaptive = async (px) => {
    await tab.evaluate((p) => {
      const s = document.getElementById('pixelError');
      s.value = String(p);
      s.dispatchEvent(new Event('input'));
      if (!document.getElementById('adaptive').checked) document.getElementById('adaptive').click();
    }, px);
    // The stats refresh every 30 frames and name the tolerance they were drawn at.
    await tab.waitForFunction((p) => document.getElementById('stats').textContent.includes(`adaptive within ${p} px`),
      { timeout: 60000 }, px);
    return tab.evaluate(() => ({ drawn: window.strataViewer.surface.refinedVertexCount,
      uniform: window.strataViewer.surface.surface.vertexCount, stats: document.getElementById('stats').textContent }));
  };
  const tight = await adaptive(1), loose = await adaptive(8);
  assert.ok(tight.drawn < tight.uniform, `adaptive draws ${tight.drawn} of ${tight.uniform} vertices`);
  assert.ok(loose.drawn < tight.drawn, `8 px draws ${loose.drawn}, 1 px ${tight.drawn}`);
  assert.match(await tab.evaluate(() => document.getElementById('stats').textContent), /adaptive within 8 px, up to level \d:\n +\d+ of \d+ vertices/);
  // The false colour shows levels in adaptive mode: its legend says so, and
  // the vertices take more than one colour (the frame mixes levels).
  const coloured = await tab.evaluate(async () => {
    const s = document.getElementById('pixelError');
    s.value = '1';
    s.dispatchEvent(new Event('input'));
    document.getElementById('falseColour').click();
    await new Promise((r) => setTimeout(r, 500));
    const g = window.strataViewer.surface.geometry, c = g.attributes.strataColour;
    const seen = new Set();
    for (let i = 0; c && i < window.strataViewer.surface.drawnVertexCount; ++i) seen.add(c.array.slice(3 * i, 3 * i + 3).join());
    return { label: document.getElementById('falseColourText').textContent, high: document.getElementById('legendHigh').textContent,
      colours: seen.size };
  });
  assert.equal(coloured.label, 'level false colour');
  assert.match(coloured.high, /^level \d$/);
  assert.ok(coloured.colours >= 2, `${coloured.colours} level colours`);
  await shot(tab, 'web-viewer-adaptive.png');
  await tab.evaluate(() => document.getElementById('falseColour').click());
  const back = await tab.evaluate(() => {
    document.getElementById('adaptive').click();
    return window.strataViewer.surface.refinedVertexCount;
  });
  assert.equal(back, tight.uniform);
  await tab.evaluate(() => document.getElementById('wireframe').click());
  await finish(tab, 10, 'web-viewer-cesiumman.png');
});

test('the viewer names the cause of a refused file', async () => {
  const tab = await open('broken.glb');
  const text = await tab.evaluate(() => document.getElementById('message').textContent);
  assert.match(text, /broken\.glb/);
  await tab.close();
});
