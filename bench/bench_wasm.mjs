// The WebAssembly runtime's frame under node, per module build: the
// CesiumMan and Fox rigs (strata-bake --control auto) posed from their own
// animation and evaluated into the render layout, as the three.js plugin
// does every frame, at levels 1-4.  A triad in the same process is the
// baseline (these machines differ 2-3x in memory bandwidth): the last
// column is a vertex's time over the time the triad streams 12 bytes.
//
//   node bench/bench_wasm.mjs [--build BUILD] [--module DIR]...
// DIR holds strata.mjs and strata.wasm (default js/dist, what
// js/wasm/build.sh makes; build another with -DSTRATA_WASM_SIMD=OFF to
// compare).
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';
import { StrataRuntime } from '../js/src/runtime.mjs';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const args = process.argv.slice(2);
const build = path.resolve(args.includes('--build') ? args[args.indexOf('--build') + 1] : path.join(root, 'build'));
const modules = args.flatMap((a, i) => (a === '--module' ? [path.resolve(args[i + 1])] : []));
if (!modules.length) modules.push(path.join(root, 'js', 'dist'));
const work = fs.mkdtempSync(path.join(os.tmpdir(), 'strata-bench-wasm-'));
const names = ['Fox', 'CesiumMan'];
for (const name of names) {
  const r = spawnSync(path.join(build, 'tools', 'strata-bake'), ['--high', path.join(root, 'tests', 'data', `${name}.glb`),
    '--control', 'auto', '-o', path.join(work, `${name}.glb`)], { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(r.stderr);
}

function triadGBs() {
  const n = 1 << 22;
  const a = new Float32Array(n), b = new Float32Array(n).fill(1), c = new Float32Array(n).fill(2);
  let best = Infinity;
  for (let k = 0; k < 5; ++k) {
    const t0 = performance.now();
    for (let i = 0; i < n; ++i) a[i] = b[i] + 3 * c[i];
    best = Math.min(best, performance.now() - t0);
  }
  return (3 * 4 * n) / (best * 1e6);
}

const triad = triadGBs();
console.log(`node ${process.version}, ${os.cpus().length} cores; JS triad ${triad.toFixed(1)} GB/s`);
console.log('| module | model | level | refined vertices | frame ms | ns / vertex | ÷ triad of 12 B |');
console.log('|---|---|---:|---:|---:|---:|---:|');
for (const dir of modules) {
  const runtime = await StrataRuntime.load({ moduleURL: pathToFileURL(path.join(dir, 'strata.mjs')).href,
    wasmURL: pathToFileURL(path.join(dir, 'strata.wasm')).href });
  for (const name of names) {
    const rig = runtime.loadRig(fs.readFileSync(path.join(work, `${name}.glb`)), name);
    for (const level of [1, 2, 3, 4]) {
      const surface = rig.createSurface(level);
      const layout = surface.createRenderMesh(rig);
      const p = new Float32Array(3 * layout.vertexCount), q = new Float32Array(3 * layout.vertexCount);
      const frames = Math.max(20, Math.round(2e6 / surface.vertexCount));
      for (let f = 0; f < 5; ++f) { surface.setAnimationTime(0, f / 30); layout.evaluate(surface, p, q); }
      const t0 = performance.now();
      for (let f = 0; f < frames; ++f) { surface.setAnimationTime(0, f / 30); layout.evaluate(surface, p, q); }
      const ms = (performance.now() - t0) / frames;
      const ns = (1e6 * ms) / surface.vertexCount;
      console.log(`| ${path.relative(root, dir) || dir} | ${name} | ${level} | ${surface.vertexCount.toLocaleString('en')} | ` +
        `${ms.toFixed(3)} | ${ns.toFixed(1)} | ${(ns * triad / 12).toFixed(2)} |`);
      layout.dispose();
      surface.dispose();
    }
    rig.dispose();
  }
}
fs.rmSync(work, { recursive: true, force: true });
