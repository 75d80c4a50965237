// The rig against the tools that rewrite glTF every day.
//
//   node js/tools/ecosystem-matrix.mjs --build BUILD_DIR [--work DIR] [--markdown docs/ECOSYSTEM.md]
//
// Bakes a bare-cage rig (spot, smooth scheme), a skinned character with
// real displacement (the penguin with its joint file) and a textured glTF
// character (CesiumMan onto itself), then passes each through
// glTF Transform commands (with and without js/gltf-transform.config.mjs),
// gltfpack with default options and a Blender 3.4 import -> export with
// default settings.  Each output goes to strata-reconstruct at the
// recommended level, and every cell must end one of two ways:
//   - the same surface: every vertex within 1e-5 of the diagonal of the
//     original rig's reconstruction (same topology, so the vertex-wise
//     distance bounds the Hausdorff distance), or
//   - exit 2 with one error line naming the cause.
// A cell that exits 0 with another surface fails the run (exit 1).  A tool
// that cannot open or write the file is recorded as such (it is the tool's
// limit, not a wrong surface).  --markdown writes the table.
import { fork, spawn, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const jsDir = path.resolve(here, '..');
const root = path.resolve(jsDir, '..');

function option(name, fallback) {
  const i = process.argv.indexOf(name);
  return i >= 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
}
const build = path.resolve(option('--build', path.join(root, 'build')));
// Without --work, a folder of its own, removed on exit (a default made
// eagerly left an empty one behind on every run that passed --work).
const given = option('--work', '');
const work = given ? path.resolve(given) : fs.mkdtempSync(path.join(os.tmpdir(), 'strata-ecosystem-'));
if (!given) process.on('exit', () => fs.rmSync(work, { recursive: true, force: true }));
const markdown = option('--markdown', '');
const bake = path.join(build, 'tools', 'strata-bake');
const reconstruct = path.join(build, 'tools', 'strata-reconstruct');
const data = path.join(root, 'tests', 'data');
const gltfTransform = path.join(jsDir, 'node_modules', '.bin', 'gltf-transform');
const config = path.join(jsDir, 'gltf-transform.config.mjs');
fs.mkdirSync(work, { recursive: true });

function run(cmd, args, opts = {}) {
  const r = spawnSync(cmd, args, { encoding: 'utf8', timeout: 300000, ...opts });
  return { code: r.status === null ? -1 : r.status, out: (r.stdout || '') + (r.stderr || ''), stderr: r.stderr || '' };
}

// run, without blocking: the cells of the matrix go on every core.
function runAsync(cmd, args, opts = {}) {
  return new Promise((resolve) => {
    const child = spawn(cmd, args, { ...opts });
    let stdout = '', stderr = '';
    child.stdout.on('data', (d) => { stdout += d; });
    child.stderr.on('data', (d) => { stderr += d; });
    const timer = setTimeout(() => child.kill('SIGKILL'), 300000);
    child.on('close', (code) => {
      clearTimeout(timer);
      resolve({ code: code === null ? -1 : code, out: stdout + stderr, stderr });
    });
    child.on('error', () => {
      clearTimeout(timer);
      resolve({ code: -1, out: stdout + stderr, stderr });
    });
  });
}

async function pool(jobs, width) {
  let next = 0;
  await Promise.all(Array.from({ length: Math.max(1, width) }, async () => {
    while (next < jobs.length) await jobs[next++]();
  }));
}

function have(cmd) {
  return spawnSync('sh', ['-c', `command -v ${cmd}`], { encoding: 'utf8' }).status === 0;
}

// Vertex positions of an OBJ.
function objVertices(file) {
  const v = [];
  for (const line of fs.readFileSync(file, 'utf8').split('\n'))
    if (line.startsWith('v ')) {
      const [, x, y, z] = line.trim().split(/\s+/);
      v.push(+x, +y, +z);
    }
  return Float64Array.from(v);
}

// A GLB's JSON and binary chunk, and a GLB made of them.
function readGlb(file) {
  const bytes = fs.readFileSync(file);
  const jsonLength = bytes.readUInt32LE(12);
  const json = JSON.parse(bytes.subarray(20, 20 + jsonLength).toString());
  const bin = bytes.length > 28 + jsonLength ? bytes.subarray(28 + jsonLength, 28 + jsonLength + bytes.readUInt32LE(20 + jsonLength)) : Buffer.alloc(0);
  return { json, bin };
}
function writeGlb(file, json, bin) {
  let text = Buffer.from(JSON.stringify(json));
  text = Buffer.concat([text, Buffer.alloc((4 - (text.length % 4)) % 4, 0x20)]);
  const head = Buffer.alloc(12), jsonHead = Buffer.alloc(8), binHead = Buffer.alloc(8);
  head.writeUInt32LE(0x46546c67, 0);
  head.writeUInt32LE(2, 4);
  head.writeUInt32LE(12 + 8 + text.length + 8 + bin.length, 8);
  jsonHead.writeUInt32LE(text.length, 0);
  jsonHead.writeUInt32LE(0x4e4f534a, 4);
  binHead.writeUInt32LE(bin.length, 0);
  binHead.writeUInt32LE(0x004e4942, 4);
  fs.writeFileSync(file, Buffer.concat([head, jsonHead, text, binHead, bin]));
}

// The translation of the unskinned node that draws the layered mesh, or
// zero: where glTF places the displaced surface.
function placement(file) {
  const { json } = readGlb(file);
  const layered = (json.meshes || []).findIndex((m) => m.extensions && m.extensions.STRATA_layered_displacement);
  const node = (json.nodes || []).find((n) => n.mesh === layered && n.skin === undefined);
  return node && node.translation ? node.translation : [0, 0, 0];
}

function diagonal(v) {
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < v.length; i += 3)
    for (let k = 0; k < 3; ++k) {
      lo[k] = Math.min(lo[k], v[i + k]);
      hi[k] = Math.max(hi[k], v[i + k]);
    }
  return Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
}

// The rigs: [name, description, strata-bake arguments].
const rigs = [
  ['spot', 'bare cage, smooth scheme', ['--high', path.join(data, 'spot_triangulated.obj'),
    '--control', path.join(data, 'spot_control_mesh.obj')]],
  ['penguin', 'skinned cage (joint file), animated', ['--high', path.join(data, 'penguin_hr.obj'),
    '--control', path.join(data, 'penguin_control_mesh.obj'), '--skeleton', path.join(data, 'penguin_joints.json')]],
  ['cesiumman', 'textured skinned glTF character', ['--high', path.join(data, 'CesiumMan.glb'),
    '--control', path.join(data, 'CesiumMan.glb')]],
  ['spot-png', 'bare cage, map as an embedded PNG sampled through UVs', ['--high', path.join(data, 'spot_triangulated.obj'),
    '--control', path.join(data, 'spot_control_mesh.obj'), '--map-coding', 'png']],
];

// glTF Transform's CLI, as installed: the matrix's cells go to CLI programs
// kept running (tools/gltf-transform-worker.mjs), each loaded with or without
// the config as `gltf-transform` loads it; the openers and the reads below
// run the command itself.  A worker that dies fails the cells it owed (a
// crash is not the tool's refusal); the others go to the workers alive.
const workers = { config: [], none: [] };
function startWorkers(withConfig, count) {
  for (let i = 0; i < count; ++i) {
    const child = fork(path.join(here, 'gltf-transform-worker.mjs'), withConfig ? ['--config', config] : [],
                       { cwd: jsDir, silent: true });
    child.stdout.resume();
    child.stderr.resume();
    const w = { child, waiting: new Map(), next: 0, exited: false };
    w.ready = new Promise((resolve) => {
      child.on('message', (m) => {
        if (m.ready) return resolve();
        w.waiting.get(m.id)(m);
        w.waiting.delete(m.id);
      });
    });
    w.gone = new Promise((resolve) => child.once('exit', resolve));
    child.on('error', () => {});
    child.on('exit', (code) => {
      w.exited = true;
      for (const done of w.waiting.values()) done({ code: -1, died: true, out: `glTF Transform's CLI exited (${code})` });
      w.waiting.clear();
    });
    workers[withConfig ? 'config' : 'none'].push(w);
  }
}
async function gtRun(argv, withConfig) {
  const pool = workers[withConfig ? 'config' : 'none'].filter((x) => !x.exited);
  if (!pool.length) return { code: -1, died: true, out: "every glTF Transform CLI program has exited" };
  const w = pool.reduce((a, b) => (b.waiting.size < a.waiting.size ? b : a));
  await Promise.race([w.ready, w.gone]);
  if (w.exited) return { code: -1, died: true, out: "glTF Transform's CLI exited before it started" };
  return new Promise((resolve) => {
    const id = w.next++;
    w.waiting.set(id, resolve);
    w.child.send({ id, argv: [...argv, ...(withConfig ? ['--config', config] : [])] });
  });
}
const gt = (args, withConfig) => (input, output) => gtRun([args[0], input, output, ...args.slice(1)], withConfig);
const gtCommand = (args, withConfig) => (input, output) =>
  run(gltfTransform, [args[0], input, output, ...args.slice(1), ...(withConfig ? ['--config', config] : [])],
      { cwd: jsDir });

// The tools: [name, with config, function(in, out) -> {code, out}].
const transformCommands = [
  ['copy'], ['dedup'], ['prune'], ['resample'], ['sparse'], ['flatten'], ['center'], ['instance'],
  ['unweld'], ['weld'], ['reorder'], ['simplify'], ['optimize'], ['meshopt'], ['draco'], ['quantize'],
  ['quantize', '--pattern', 'TEXCOORD_*'], ['dequantize'],
  // Texture commands (sharp, from npm): they leave the map, which is data, alone.
  ['resize', '--width', '64', '--height', '64'], ['webp'], ['jpeg'], ['png'], ['avif'],
  // And the rest of the everyday commands that touch meshes or materials.
  ['join'], ['tangents'], ['unwrap'], ['palette'], ['metalrough'], ['unlit'],
];
const tools = [];
for (const c of transformCommands) tools.push([`gltf-transform ${c.join(' ')}`, 'config', gt(c, true)]);
for (const c of transformCommands.slice(0, transformCommands.length - 6))
  tools.push([`gltf-transform ${c.join(' ')}`, 'none', gt(c, false)]);
// A rig merged with another model: in a scene of its own (merge's default,
// which a viewer shows alone), or in one scene with it.
for (const [label, extra] of [['merge with Fox.glb', []], ['merge --merge-scenes with Fox.glb', ['--merge-scenes']]])
  for (const withConfig of [true, false])
    tools.push([`gltf-transform ${label}`, withConfig ? 'config' : 'none',
      (input, output) => gtRun(['merge', input, path.join(data, 'Fox.glb'), output, ...extra], withConfig)]);
tools.push(['gltfpack', 'defaults', (input, output) => runAsync('gltfpack', ['-i', input, '-o', output])]);
tools.push(['Blender 3.4 import -> export', 'defaults', (input, output) =>
  runAsync('blender', ['-b', '--factory-startup', '--python', path.join(root, 'tools', 'blender_roundtrip.py'), '--',
                  input, output])]);

const { default: Ajv2020 } = await import('ajv/dist/2020.js');
const validateLayer = new Ajv2020({ strict: false }).compile(JSON.parse(fs.readFileSync(
  path.join(root, 'docs', 'schema', 'mesh.STRATA_layered_displacement.schema.json'), 'utf8')));

const rows = [];
const jobs = [];  // one per cell, run concurrently once every rig is baked
let wrong = 0;
for (const [name, description, args] of rigs) {
  const rig = path.join(work, `${name}.glb`);
  const baked = run(bake, [...args, '--error-levels', 'none', '-o', rig]);
  if (baked.code !== 0) {
    console.error(`bake of ${name} failed:\n${baked.out}`);
    process.exit(1);
  }
  // The layer as written validates against the extension's JSON schema.
  {
    const { json } = readGlb(rig);
    for (const mesh of json.meshes.filter((m) => m.extensions && m.extensions.STRATA_layered_displacement))
      if (!validateLayer(mesh.extensions.STRATA_layered_displacement)) {
        console.error(`${name}: the layer does not validate against the schema: ${JSON.stringify(validateLayer.errors)}`);
        process.exit(1);
      }
    if (!json.meshes.some((m) => m.extensions && m.extensions.STRATA_layered_displacement)) {
      console.error(`${name}: no mesh carries STRATA_layered_displacement`);
      process.exit(1);
    }
  }
  const ref = path.join(work, `${name}_ref.obj`);
  const r = run(reconstruct, [rig, '-o', ref]);
  if (r.code !== 0) {
    console.error(`reconstruct of ${name} failed:\n${r.out}`);
    process.exit(1);
  }
  const refV = objVertices(ref);
  const tolerance = 1e-5 * diagonal(refV);
  // Animated rigs are also compared posed (0.7 s into the first animation):
  // a command that quantises skin weights moves the posed surface by what
  // it rounded away, and nothing else may move it.
  const animated = name === 'penguin' || name === 'cesiumman';
  const posedRef = path.join(work, `${name}_ref_posed.obj`);
  if (animated && run(reconstruct, [rig, '--time', '0.7', '-o', posedRef]).code !== 0) {
    console.error(`posed reconstruct of ${name} failed`);
    process.exit(1);
  }
  for (const [tool, how, fn] of tools) {
    const slot = rows.length;
    rows.push(null);
    const put = (row) => { rows[slot] = row; };
    jobs.push(async () => {
      const tag = `${name}_${tool.replace(/[^a-z0-9]+/gi, '_')}_${how}`;
      const out = path.join(work, `${tag}.glb`);
      if ((tool.startsWith('gltfpack') && !have('gltfpack')) || (tool.startsWith('Blender') && !have('blender'))) {
        put([name, tool, how, 'MISSING TOOL', 'not installed (cmake/install-deps.sh installs it)']);
        ++wrong;
        return;
      }
      const t = await fn(rig, out);
      if (t.died) {
        put([name, tool, how, 'TOOL CRASHED', t.out]);
        ++wrong;
        return;
      }
      if (t.code !== 0 || !fs.existsSync(out)) {
        const why = t.out.split('\n').map((l) => l.trim()).filter((l) =>
          /error|failed|requires|compressed/i.test(l)).pop() || `exit ${t.code}`;
        put([name, tool, how, 'tool cannot process it', why.slice(0, 160)]);
        return;
      }
      const recon = path.join(work, `${tag}.obj`);
      const s = await runAsync(reconstruct, [out, '-o', recon]);
      if (s.code === 0) {
        const v = objVertices(recon);
        // In place, or, for a rig the tool moved whole by its node (center),
        // moved by exactly that node's move: its translation added.
        const [from, to] = [rig, out].map(placement);
        const by = [0, 1, 2].map((k) => to[k] - from[k]);
        const apart = (shift) => {
          let most = v.length === refV.length ? 0 : Infinity;
          for (let i = 0; i < v.length && most < Infinity; i += 3)
            most = Math.max(most, Math.hypot(v[i] - refV[i] - shift[0], v[i + 1] - refV[i + 1] - shift[1], v[i + 2] - refV[i + 2] - shift[2]));
          return most;
        };
        let max = apart([0, 0, 0]), movedBy = '';
        if (max > tolerance && Math.hypot(...by) > 0 && apart(by) <= tolerance) {
          max = apart(by);
          movedBy = `, moved by its node's translation (${by.map((x) => x.toPrecision(3)).join(', ')})`;
        }
        // A carried layer is still the extension's schema.
        const layer = readGlb(out).json.meshes.map((m) => m.extensions && m.extensions.STRATA_layered_displacement).find(Boolean);
        if (layer && !validateLayer(layer)) {
          put([name, tool, how, 'SCHEMA', JSON.stringify(validateLayer.errors).slice(0, 200)]);
          ++wrong;
          return;
        }
        let posed = '';
        if (max <= tolerance && animated) {
          const posedOut = path.join(work, `${tag}_posed.obj`);
          const p = await runAsync(reconstruct, [out, '--time', '0.7', '-o', posedOut]);
          const a = objVertices(posedRef), b = p.code === 0 ? objVertices(posedOut) : new Float64Array(0);
          // Up to one translation of the whole scene (center moves the root).
          const shift = [0, 0, 0];
          for (let i = 0; i < a.length && a.length === b.length; i += 3)
            for (let k = 0; k < 3; ++k) shift[k] += (b[i + k] - a[i + k]) / (a.length / 3);
          let worst = a.length === b.length ? 0 : Infinity;
          for (let i = 0; i < a.length && worst < Infinity; i += 3)
            worst = Math.max(worst, Math.hypot(a[i] + shift[0] - b[i], a[i + 1] + shift[1] - b[i + 1], a[i + 2] + shift[2] - b[i + 2]));
          worst /= diagonal(a);
          const moved = Math.hypot(...shift) / diagonal(a);
          posed = `; posed at 0.7 s ${worst.toExponential(1)}${moved > 1e-6 ? ` after the scene's move by ${moved.toExponential(1)}` : ''}`;
          if (!(worst <= 5e-3)) {
            put([name, tool, how, 'WRONG POSE', `posed at 0.7 s: max vertex distance ${worst.toExponential(2)} of the diagonal`]);
            ++wrong;
            return;
          }
        }
        if (max <= tolerance) {
          put([name, tool, how, 'same surface', `max vertex distance ${(max / (tolerance / 1e-5)).toExponential(1)} of the diagonal${movedBy}${posed}`]);
        } else {
          put([name, tool, how, 'WRONG SURFACE', v.length === refV.length
            ? `max vertex distance ${(max / (tolerance / 1e-5)).toExponential(2)} of the diagonal`
            : `${v.length / 3} vertices, the rig's surface has ${refV.length / 3}`]);
          ++wrong;
        }
      } else {
        const errors = s.stderr.split('\n').filter((l) => l.includes(': error: '));
        if (s.code === 2 && errors.length === 1) {
          put([name, tool, how, 'refused', errors[0].replace(/^strata-reconstruct: error: [^:]*: /, '')]);
        } else {
          put([name, tool, how, 'BAD EXIT', `exit ${s.code}: ${s.stderr.trim().slice(0, 200)}`]);
          ++wrong;
        }
      }
    });
  }
}
startWorkers(true, os.cpus().length);
startWorkers(false, os.cpus().length);
await pool(jobs, os.cpus().length);
for (const w of [...workers.config, ...workers.none]) w.child.kill();

// A carried file that is then damaged or edited is refused with the cause:
// spot reordered with the config (so it carries \`baked\` and the tags),
// then changed by hand.
const tampers = [];
{
  const carried = path.join(work, 'spot_gltf_transform_reorder_config.glb');
  const cases = [
    ['the tags removed', /lost the _STRATA_VERTEX/, (json) => {
      for (const m of json.meshes) for (const p of m.primitives) delete p.attributes._STRATA_VERTEX;
    }],
    ['the baked copy pointed at other data', /is not the one its "control" record describes/, (json) => {
      const part = json.meshes[0].extensions.STRATA_layered_displacement.baked.parts[0];
      part.POSITION = json.meshes[0].primitives[0].attributes.POSITION;
    }],
    ['a triangle dropped', /triangles but was baked with/, (json) => {
      const acc = json.accessors[json.meshes[0].primitives[0].indices];
      acc.count -= 3;
    }],
    ['the mesh scaled unevenly by its node', /scale the rig unevenly/, (json) => {
      json.nodes.find((n) => n.mesh === 0).scale = [2, 1, 1];
    }],
  ];
  for (const [label, expect, edit] of cases) {
    if (!fs.existsSync(carried)) {
      ++wrong;
      tampers.push([label, 'FAILED', 'glTF Transform reorder with the config wrote no file to edit']);
      continue;
    }
    const { json, bin } = readGlb(carried);
    edit(json);
    const file = path.join(work, `tampered_${label.replace(/[^a-z0-9]+/gi, '_')}.glb`);
    writeGlb(file, json, bin);
    const r = run(reconstruct, [file, '-o', file.replace(/\.glb$/, '.obj')]);
    const errors = r.stderr.split('\n').filter((l) => l.includes(': error: '));
    const ok = r.code === 2 && errors.length === 1 && expect.test(errors[0]);
    if (!ok) ++wrong;
    tampers.push([label, ok ? 'refused' : `FAILED (exit ${r.code})`,
                  (errors[0] || r.out.trim().split('\n').pop() || '').replace(/^strata-reconstruct: error: [^:]*: /, '')]);
  }
  // Moved and scaled alike by its node (an editor placing the model): glTF
  // draws the displaced surface through the node, and so does Strata.
  if (fs.existsSync(carried)) {
    const { json, bin } = readGlb(carried);
    Object.assign(json.nodes.find((n) => n.mesh === 0), { translation: [0.5, 0, 0], scale: [2, 2, 2] });
    const file = path.join(work, 'tampered_placed.glb');
    writeGlb(file, json, bin);
    const r = run(reconstruct, [file, '-o', file.replace(/\.glb$/, '.obj')]);
    const refV = objVertices(path.join(work, 'spot_ref.obj'));
    const v = r.code === 0 ? objVertices(file.replace(/\.glb$/, '.obj')) : new Float64Array(0);
    let max = v.length === refV.length ? 0 : Infinity;
    for (let i = 0; i < v.length && max < Infinity; i += 3)
      max = Math.max(max, Math.hypot(v[i] - 2 * refV[i] - 0.5, v[i + 1] - 2 * refV[i + 1], v[i + 2] - 2 * refV[i + 2]));
    max /= 2 * diagonal(refV);
    const ok = max <= 1e-5;
    if (!ok) ++wrong;
    tampers.push(['the mesh moved by 0.5 and scaled 2x by its node', ok ? 'drawn there' : `WRONG SURFACE (exit ${r.code})`,
                  r.code === 0 ? `max vertex distance ${max.toExponential(1)} of the diagonal from the reference moved and scaled so`
                    : r.stderr.trim().split('\n').pop()]);
  }
}

// Valid glTF that other tools write is read: gltf-transform optimize's
// output of Fox and CesiumMan (meshopt, quantised, pruned) and of a
// character with morph targets made sparse (accessors without bufferViews,
// sparse accessors), each baked onto itself and refined plain.
async function morphCharacter(file) {
  const { Document, NodeIO } = await import('@gltf-transform/core');
  const { sparse } = await import('@gltf-transform/functions');
  const doc = new Document();
  const buffer = doc.createBuffer();
  const n = 8;  // a strip of 2n triangles with one morph target touching two vertices
  const pos = new Float32Array(3 * 2 * (n + 1)), delta = new Float32Array(pos.length), idx = [];
  for (let i = 0; i <= n; ++i) {
    pos.set([i / n, 0, 0], 6 * i);
    pos.set([i / n, 1, 0], 6 * i + 3);
  }
  delta.set([0, 0, 0.25], 6 * 3);
  delta.set([0, 0, 0.25], 6 * 3 + 3);
  for (let i = 0; i < n; ++i) idx.push(2 * i, 2 * i + 2, 2 * i + 1, 2 * i + 1, 2 * i + 2, 2 * i + 3);
  const acc = (array, type) => doc.createAccessor().setArray(array).setType(type).setBuffer(buffer);
  const target = doc.createPrimitiveTarget().setAttribute('POSITION', acc(delta, 'VEC3'));
  const prim = doc.createPrimitive().setAttribute('POSITION', acc(pos, 'VEC3'))
    .setIndices(acc(new Uint16Array(idx), 'SCALAR')).addTarget(target);
  const mesh = doc.createMesh('morph').addPrimitive(prim).setWeights([0]);
  doc.createScene().addChild(doc.createNode('morph').setMesh(mesh));
  await doc.transform(sparse({ ratio: 0.5 }));
  await new NodeIO().write(file, doc);
}

const reads = [];
{
  const morph = path.join(work, 'morph.glb');
  await morphCharacter(morph);
  const inputs = [['Fox', path.join(data, 'Fox.glb'), true], ['CesiumMan', path.join(data, 'CesiumMan.glb'), true],
                  ['morph-target strip', morph, true],
                  ['(as gltf-transform sparse wrote it) morph-target strip', morph, false]];
  for (const [label, input, optimize] of inputs) {
    const optimized = optimize ? path.join(work, `${path.basename(input, '.glb')}_optimized.glb`) : input;
    const o = optimize ? run(gltfTransform, ['optimize', input, optimized, '--texture-compress', 'false'], { cwd: jsDir })
                       : { code: 0, out: '' };
    const json = fs.existsSync(optimized) && fs.statSync(optimized).size > 20 ? readGlb(optimized).json : { accessors: [] };
    const noView = json.accessors.filter((a) => a.bufferView === undefined).length;
    const sparseCount = json.accessors.filter((a) => a.sparse).length;
    const b = o.code === 0 ? run(bake, ['--high', optimized, '--control', optimized, '--error-levels', 'none', '-o',
                                        path.join(work, `${path.basename(optimized, '.glb')}_rig.glb`)])
                           : { code: -1, out: o.out };
    const r = o.code === 0 ? run(reconstruct, [optimized, '--no-displacement', '--level', '1', '-o',
                                               path.join(work, `${path.basename(optimized, '.glb')}.obj`)])
                           : { code: -1, out: '' };
    const ok = b.code === 0 && r.code === 0;
    if (!ok) ++wrong;
    reads.push([optimize ? `gltf-transform optimize of ${label}` : label, `${noView} without bufferView, ${sparseCount} sparse`, ok ? 'baked and refined'
      : `FAILED: ${(b.code ? b.out : r.out).trim().split('\n').pop().slice(0, 200)}`]);
  }
}

// A character whose texture glTF Transform made WebP or AVIF (`gltf-transform
// webp` / `avif`; EXT_texture_webp or EXT_texture_avif, no PNG or JPEG
// left): --control auto re-bakes its colour from that image at the
// texture's own size, and names nothing as not decoded (Strata decoded PNG
// and JPEG only: it re-baked white).
for (const [format, extension, name] of [['webp', 'EXT_texture_webp', 'WebP'], ['avif', 'EXT_texture_avif', 'AVIF']]) {
  const coded = path.join(work, `CesiumMan_${format}.glb`);
  const o = run(gltfTransform, [format, path.join(data, 'CesiumMan.glb'), coded], { cwd: jsDir });
  const json = o.code === 0 ? readGlb(coded).json : { extensionsUsed: [] };
  const b = o.code === 0 ? run(bake, ['--high', coded, '--control', 'auto', '--error-levels', 'none', '-o',
                                      path.join(work, `CesiumMan_${format}_rig.glb`)]) : { code: -1, out: o.out };
  const colour = (/colour\s+(.*)/.exec(b.out) || [])[1] || '';
  const ok = b.code === 0 && (json.extensionsUsed || []).includes(extension) &&
             !/does not decode|cannot be decoded/.test(b.out) && /1024x1024 base colour texture/.test(colour);
  if (!ok) ++wrong;
  reads.push([`gltf-transform ${format} of CesiumMan, then \`--control auto\``, `its texture only in ${extension}`,
              ok ? `colour re-baked from the ${name}: ${colour.trim()}`
                 : `FAILED: ${(b.out.match(/.*(decode|error).*/) || [colour || b.out.trim().split('\n').pop()])[0].slice(0, 200)}`]);
}

// Which tools open which mesh coding: the claims README.md makes, checked.
// [tool, expected for plain, meshopt, draco, run(input, output)].
const openers = [
  ['Blender 3.4 importer (Debian)', [true, false, false], (i, o) =>
    run('blender', ['-b', '--factory-startup', '--python', path.join(root, 'tools', 'blender_roundtrip.py'), '--', i, o])],
  ['gltfpack (Debian)', [true, false, false], (i, o) => run('gltfpack', ['-i', i, '-o', o])],
  ['glTF Transform 4.5 with the config', [true, true, true], gtCommand(['copy'], true)],
  ['strata-reconstruct', [true, true, true], (i, o) => run(reconstruct, [i, '-o', o.replace(/\.glb$/, '.obj')])],
];
const codings = ['plain', 'meshopt', 'draco'];
const opens = [];
for (const coding of codings) {
  const rig = path.join(work, `spot_${coding}.glb`);
  const b = run(bake, [...rigs[0][2], '--mesh-coding', coding, '--error-levels', 'none', '-o', rig]);
  if (b.code !== 0) {
    console.error(`bake of spot with --mesh-coding ${coding} failed:\n${b.out}`);
    process.exit(1);
  }
  opens.push([coding, fs.statSync(rig).size]);
}
const openRows = [];
for (const [tool, expected, fn] of openers) {
  const cells = [];
  for (const [k, coding] of codings.entries()) {
    const out = path.join(work, `open_${coding}_${tool.replace(/[^a-z0-9]+/gi, '_')}.glb`);
    const r = await fn(path.join(work, `spot_${coding}.glb`), out);
    const opened = r.code === 0;
    if (opened !== expected[k]) ++wrong;
    cells.push(`${opened ? 'opens' : 'does not open'}${opened !== expected[k] ? ' (README says otherwise: FAILED)' : ''}`);
  }
  openRows.push([tool, ...cells]);
}

const escape = (s) => s.replace(/\|/g, '\\|');
let table = '| rig | tool | extension support | result | detail |\n|---|---|---|---|---|\n';
for (const r of rows) table += `| ${r.map(escape).join(' | ')} |\n`;
let tamperTable = '| spot, reordered with the config, then | result | Strata says |\n|---|---|---|\n';
for (const r of tampers) tamperTable += `| ${r.map(escape).join(' | ')} |\n`;
let readTable = '| input | accessors | Strata |\n|---|---|---|\n';
for (const r of reads) readTable += `| ${r.map(escape).join(' | ')} |\n`;
let openTable = `| tool | ${opens.map(([c, n]) => `\`--mesh-coding ${c}\` (spot: ${n} B)`).join(' | ')} |\n|---|---|---|---|\n`;
for (const r of openRows) openTable += `| ${r.map(escape).join(' | ')} |\n`;
console.log(table);
console.log(tamperTable);
console.log(readTable);
console.log(openTable);
console.log(`${rows.length + tampers.length + reads.length + openRows.length * codings.length - wrong} passed, ${wrong} failed`);
if (markdown) {
  const described = rigs.map(([n, d]) => `\`${n}\` (${d})`).join(', ');
  const text = `# The rig through other tools

Generated by \`node js/tools/ecosystem-matrix.mjs --build build --markdown docs/ECOSYSTEM.md\`
(run in CI by ctest as \`ecosystem.matrix\`).  Rigs: ${described}, each
baked with default flags.  Every output is reconstructed by
\`strata-reconstruct\` at the recommended level and compared with the
original rig's reconstruction.  A cell passes with the **same surface**
(every vertex within 1e-5 of the diagonal) or when Strata **refuses** the
file with one line naming the cause; **no cell may draw another surface
with exit 0**.  "config" runs glTF Transform with
\`--config js/gltf-transform.config.mjs\` (the STRATA_layered_displacement
extension registered); "none" runs it as installed.  Each cell is one command
line of glTF Transform's CLI, run by its own program kept loaded between
files (\`js/tools/gltf-transform-worker.mjs\`); the last table runs the
\`gltf-transform\` command itself.  "tool cannot process it" is the tool's
own refusal.

${table}
Commands that renumber or move the control mesh (weld, unweld, reorder,
meshopt, draco, quantize) keep the surface **with the config**: its
extension tags every control vertex with its baked number and writes the
baked control mesh beside the layer (docs/STRATA_layered_displacement.md,
"Carrying the layer").  The rest pose is then the same bit for bit; posed,
the surface moves only by the skin weights the command quantised ("posed
at 0.7 s", a fraction of the diagonal, after any translation of the
whole scene such as center's).  Commands that change the
triangles (simplify, optimize where it simplifies) are refused.  A rig
without skin that a command or an editor moves, turns or scales alike as a
whole through its node (center) is drawn where the node puts it, as glTF
draws it, its displacements scaled with it ("moved by its node's
translation"); a node that scales it unevenly or shears it would bend the
surface out of its baked shape, and one that mirrors it turns its faces
over (renumbering the refinement the values follow): both are refused.  A rig merged with another
model (\`gltf-transform merge\`) is read in its own scene, the default one
that a viewer shows, and the other scene's mesh is named in a warning;
merged into one scene with it (\`--merge-scenes\`), it is refused, naming
the other model's mesh (it was refused as "welded, split, simplified or
rebuilt").

## A carried file, damaged or edited afterwards, is refused (or, moved whole, drawn there)

${tamperTable}
## Valid glTF from other tools is read

\`gltf-transform optimize\` (meshopt, quantisation) of two characters and of
a strip with a morph target, and that strip as \`sparse\` wrote it (a morph
target as a sparse accessor without a bufferView); each is baked onto itself
with \`strata-bake\` and refined plain with \`strata-reconstruct
--no-displacement\`.  And CesiumMan through \`gltf-transform webp\` and
\`gltf-transform avif\` (its texture only in EXT_texture_webp or
EXT_texture_avif, as glTF Transform's WebP and AVIF compression leave it),
baked with \`--control auto\`: its colour is re-baked from the WebP or AVIF
(Strata decodes PNG, JPEG and, with libwebp and libavif, WebP and AVIF;
before, it re-baked the colour factor alone, white, and named the texture as
not decoded).

${readTable}
## Which tools open which mesh coding

The default rig (\`--mesh-coding plain\`) opens everywhere; the smaller
codings do not open in Debian's Blender 3.4 (no Draco library, no
EXT_meshopt_compression) or gltfpack (which refuses files that are already
meshopt-coded, and is built without Draco).  These are the claims README.md
makes; the script fails when a tool disagrees.

${openTable}`;
  fs.writeFileSync(markdown, text);
}
process.exit(wrong ? 1 : 0);
