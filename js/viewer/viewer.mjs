// Strata's web viewer: three.js with StrataLoaderPlugin.  Drop a rig (or any
// .glb); orbit; pick the level, the animation and its time; show the cage,
// wireframe, or the displacement in false colour; draw adaptively (each
// control face at the lowest level within a pixel tolerance of the chosen
// one, for the camera); read the file's numbers.
// ?rig=URL loads a file at start (the smoke test uses it).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { StrataLoaderPlugin } from 'strata-layered/three';

const $ = (id) => document.getElementById(id);
const view = $('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(view.clientWidth, view.clientHeight);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x2b2d31);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404048, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 2.0);
sun.position.set(1, 2, 1.5);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(40, view.clientWidth / view.clientHeight, 0.01, 1000);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = true;

const state = {
  gltf: null, surface: null, mixer: null, action: null, playing: true, bytes: 0, name: '',
  frameMs: 0, frames: 0, errors: null, falseColour: false, diagonal: 1, adaptive: null,
};
window.strataViewer = state;  // for tests and the console

const draco = new DRACOLoader().setDecoderPath(new URL('../node_modules/three/examples/jsm/libs/draco/', import.meta.url).href);

function message(text) {
  $('message').textContent = text || '';
}

function frameCamera(object) {
  const box = new THREE.Box3().setFromObject(object, true);
  const size = box.getSize(new THREE.Vector3());
  const centre = box.getCenter(new THREE.Vector3());
  const radius = Math.max(size.length() / 2, 1e-6);
  state.diagonal = size.length() || 1;
  const distance = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
  camera.position.copy(centre).add(new THREE.Vector3(0.4, 0.25, 1).normalize().multiplyScalar(distance));
  camera.near = distance / 100;
  camera.far = distance * 10;
  camera.updateProjectionMatrix();
  controls.target.copy(centre);
  controls.update();
}

// The deviation of each level from the finest one the viewer measures (the
// level above the recommended one, at most 6): from every vertex of the
// finest surface to the nearest point of the level's triangles, in the
// bind pose, relative to the diagonal.  A grid over the triangles keeps it
// near linear.
function closestOnTriangle(p, a, b, c) {
  const ab = b.clone().sub(a), ac = c.clone().sub(a), ap = p.clone().sub(a);
  const d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a.clone();
  const bp = p.clone().sub(b), d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b.clone();
  const vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a.clone().addScaledVector(ab, d1 / (d1 - d3));
  const cp = p.clone().sub(c), d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c.clone();
  const vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a.clone().addScaledVector(ac, d2 / (d2 - d6));
  const va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return b.clone().addScaledVector(c.clone().sub(b), (d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const denom = 1 / (va + vb + vc);
  return a.clone().addScaledVector(ab, vb * denom).addScaledVector(ac, vc * denom);
}

function deviation(fine, coarse, triangles, diagonal) {
  const box = new THREE.Box3();
  for (let i = 0; i < coarse.length; i += 3) box.expandByPoint(new THREE.Vector3(coarse[i], coarse[i + 1], coarse[i + 2]));
  const cells = Math.max(1, Math.round(Math.cbrt(triangles.length / 3)));
  const size = box.getSize(new THREE.Vector3()).addScalar(1e-9);
  const cellOf = (x, y, z) => [x, y, z].map((v, k) => Math.min(cells - 1, Math.max(0,
    Math.floor((v - box.min.getComponent(k)) / size.getComponent(k) * cells))));
  const grid = new Map();
  const v = (i) => new THREE.Vector3(coarse[3 * i], coarse[3 * i + 1], coarse[3 * i + 2]);
  for (let t = 0; t < triangles.length; t += 3) {
    const tb = new THREE.Box3().setFromPoints([v(triangles[t]), v(triangles[t + 1]), v(triangles[t + 2])]);
    const lo = cellOf(tb.min.x, tb.min.y, tb.min.z), hi = cellOf(tb.max.x, tb.max.y, tb.max.z);
    for (let x = lo[0]; x <= hi[0]; ++x) for (let y = lo[1]; y <= hi[1]; ++y) for (let z = lo[2]; z <= hi[2]; ++z) {
      const key = (x * cells + y) * cells + z;
      if (!grid.has(key)) grid.set(key, []);
      grid.get(key).push(t);
    }
  }
  let sum = 0, worst = 0;
  const p = new THREE.Vector3();
  for (let i = 0; i < fine.length; i += 3) {
    p.set(fine[i], fine[i + 1], fine[i + 2]);
    const c = cellOf(p.x, p.y, p.z);
    // The triangles of the cells at Chebyshev distance r from c, nearest kept.
    let best = Infinity;
    const ring = (r) => {
      for (let x = Math.max(0, c[0] - r); x <= Math.min(cells - 1, c[0] + r); ++x)
        for (let y = Math.max(0, c[1] - r); y <= Math.min(cells - 1, c[1] + r); ++y)
          for (let z = Math.max(0, c[2] - r); z <= Math.min(cells - 1, c[2] + r); ++z) {
            if (Math.max(Math.abs(x - c[0]), Math.abs(y - c[1]), Math.abs(z - c[2])) !== r) continue;
            const list = grid.get((x * cells + y) * cells + z);
            if (list) for (const t of list)
              best = Math.min(best, closestOnTriangle(p, v(triangles[t]), v(triangles[t + 1]), v(triangles[t + 2])).distanceTo(p));
          }
    };
    let r = 0;
    while (best === Infinity && r <= cells) ring(r++);
    ring(r);  // one more ring: a nearer triangle may sit in the next cells
    sum += best * best;
    worst = Math.max(worst, best);
  }
  return { rms: Math.sqrt(sum / (fine.length / 3)) / diagonal, max: worst / diagonal };
}

function measureLevels(mesh) {
  const rig = mesh.rig;
  const finest = Math.min(6, rig.recommendedLevel + 1);
  const surfaces = [];
  try {
    for (let l = 0; l <= finest; ++l) {
      const s = rig.createSurface(l);
      surfaces.push({ level: l, positions: s.evaluate().positions, triangles: s.triangles(), count: s.vertexCount });
      s.dispose();
      if (s.vertexCount > 400000) break;
    }
  } catch (e) {
    return [];
  }
  const fine = surfaces[surfaces.length - 1];
  let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < fine.positions.length; ++i) {
    lo[i % 3] = Math.min(lo[i % 3], fine.positions[i]);
    hi[i % 3] = Math.max(hi[i % 3], fine.positions[i]);
  }
  const diagonal = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) || 1;
  return surfaces.map((s) => ({
    level: s.level, vertices: s.count, triangles: s.triangles.length / 3,
    ...(s === fine ? { rms: 0, max: 0 } : deviation(fine.positions, s.positions, s.triangles, diagonal)),
    reference: fine.level,
  }));
}

function updateStats() {
  const lines = [];
  lines.push(`${state.name}: ${(state.bytes / 1024).toFixed(1)} KB`);
  const m = state.surface;
  if (m) {
    const rig = m.rig;
    lines.push(`control: ${rig.controlVertexCount} vertices, scheme ${rig.scheme}`);
    // The tolerance the last frame was drawn at, not the slider's (which
    // may have moved since): the figures beside it are that frame's.
    if (state.adaptive && state.adaptive.pixelError !== undefined)
      lines.push(`adaptive within ${state.adaptive.pixelError} px, up to level ${m.level}:`,
        `  ${m.refinedVertexCount} of ${m.surface.vertexCount} vertices,`);
    else
      lines.push(`level ${m.level} (recommended ${rig.recommendedLevel}): ${m.refinedVertexCount} vertices,`);
    lines.push(`  ${m.drawnIndexCount / 3} triangles, ${m.drawnVertexCount} drawn vertices`);
    lines.push(`joints ${rig.jointCount}, animations ${rig.animationCount}`);
    lines.push(`surface update: ${state.frameMs.toFixed(2)} ms / frame`);
    if (state.errors && state.errors.length) {
      lines.push(`deviation from level ${state.errors[0].reference}, % of diagonal:`);
      for (const e of state.errors)
        lines.push(`  L${e.level}: rms ${(100 * e.rms).toFixed(4)}  max ${(100 * e.max).toFixed(4)}`);
    }
  } else if (state.gltf) {
    lines.push('no Strata layer: drawn as three.js loads it');
  }
  $('stats').textContent = lines.join('\n');
}

// Lambert shading tinted by the strataColour attribute.
function falseColourMaterial() {
  const material = new THREE.MeshLambertMaterial({ wireframe: $('wireframe').checked });
  material.onBeforeCompile = (shader) => {
    shader.vertexShader = shader.vertexShader.replace('#include <color_pars_vertex>',
      'attribute vec3 strataColour;\nvarying vec3 vStrataColour;')
      .replace('#include <color_vertex>', 'vStrataColour = strataColour;');
    shader.fragmentShader = shader.fragmentShader.replace('#include <color_pars_fragment>', 'varying vec3 vStrataColour;')
      .replace('#include <color_fragment>', 'diffuseColor.rgb *= vStrataColour;');
  };
  return material;
}

function applyFalseColour() {
  const m = state.surface;
  if (!m) return;
  $('legend').style.display = state.falseColour ? 'block' : 'none';
  if (!state.falseColour) {
    if (m.userData.savedMaterial) m.material = m.userData.savedMaterial;
    m.userData.savedMaterial = null;
    return;
  }
  // A value in -1 .. 1 per drawn vertex: the displacement over its largest,
  // or in adaptive mode the finest level of the triangles it is drawn in,
  // from level 0 (-1) to the surface's (+1).
  const n = m.geometry.attributes.position.count;
  const value = new Float32Array(n);
  let scale = 0;
  if (state.adaptive && m.adaptiveMesh) {
    const levels = m.surface.adaptiveTriangleLevels(), index = m.geometry.index.array;
    value.fill(-1);
    for (let t = 0; t < levels.length; ++t)
      for (let k = 0; k < 3; ++k)
        value[index[3 * t + k]] = Math.max(value[index[3 * t + k]], m.level ? (2 * levels[t]) / m.level - 1 : 1);
  } else {
    const d = m.surface.displacements();
    for (const x of d) scale = Math.max(scale, Math.abs(x));
    scale = scale || 1;
    for (let i = 0; i < n; ++i) value[i] = d[m.refinedVertex[i]] / scale;
  }
  const colours = new Float32Array(3 * n);
  const low = new THREE.Color(0x3b4cc0), mid = new THREE.Color(0xdddddd), high = new THREE.Color(0xb40426);
  const c = new THREE.Color();
  for (let i = 0; i < n; ++i) {
    const t = value[i];
    c.copy(mid).lerp(t < 0 ? low : high, Math.min(1, Math.abs(t)));
    colours.set([c.r, c.g, c.b], 3 * i);
  }
  m.geometry.setAttribute('strataColour', new THREE.BufferAttribute(colours, 3));
  if (!m.userData.savedMaterial) m.userData.savedMaterial = m.material;
  if (m.userData.falseMaterial) {
    m.userData.falseMaterial.wireframe = $('wireframe').checked;
    m.material = m.userData.falseMaterial;
  } else {
    m.material = m.userData.falseMaterial = falseColourMaterial();
  }
  if (state.adaptive && m.adaptiveMesh) {
    $('legendLow').textContent = 'level 0';
    $('legendMid').textContent = m.level % 2 ? '' : `level ${m.level / 2}`;
    $('legendHigh').textContent = `level ${m.level}`;
  } else {
    $('legendMid').textContent = '0';
    $('legendLow').textContent = (-scale).toPrecision(3);
    $('legendHigh').textContent = `+${scale.toPrecision(3)}`;
  }
  state.colouredVersion = m.adaptiveVersionShown;
}

function applyToggles() {
  const m = state.surface;
  if (!m) return;
  const materials = [].concat(m.material);
  for (const mat of materials) mat.wireframe = $('wireframe').checked;
  for (const c of m.cage) {
    c.visible = $('cage').checked;
    if (c.visible) {
      c.material = c.userData.cageMaterial || (c.userData.cageMaterial =
        new THREE.MeshBasicMaterial({ color: 0xffd166, wireframe: true, depthTest: false, transparent: true, opacity: 0.6 }));
      c.renderOrder = 1;
    }
  }
}

function setAnimation(index) {
  if (!state.mixer) return;
  state.mixer.stopAllAction();
  state.action = index >= 0 ? state.mixer.clipAction(state.gltf.animations[index]) : null;
  if (state.action) {
    state.action.play();
    $('time').max = String(state.action.getClip().duration);
  }
}

async function load(source, name, bytes) {
  message('loading ' + name + ' ...');
  const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder).setDRACOLoader(draco);
  loader.register((parser) => new StrataLoaderPlugin(parser, { name, level: $('level').dataset.asked || 'recommended' }));
  let gltf;
  try {
    gltf = typeof source === 'string' ? await loader.loadAsync(source) : await loader.parseAsync(source, '');
  } catch (e) {
    message(`${name}: ${e.message}`);
    state.ready = true;
    state.error = e.message;
    return;
  }
  if (state.gltf) {
    scene.remove(state.gltf.scene);
    if (state.surface) state.surface.dispose();
  }
  state.gltf = gltf;
  state.surface = gltf.userData.strata || null;
  state.name = name;
  state.bytes = bytes;
  state.errors = null;
  scene.add(gltf.scene);
  state.mixer = gltf.animations.length ? new THREE.AnimationMixer(gltf.scene) : null;
  const select = $('animation');
  select.innerHTML = '';
  const none = document.createElement('option');
  none.value = '-1';
  none.textContent = gltf.animations.length ? '(rest pose)' : '(none)';
  select.appendChild(none);
  gltf.animations.forEach((a, i) => {
    const o = document.createElement('option');
    o.value = String(i);
    o.textContent = a.name || `animation ${i}`;
    select.appendChild(o);
  });
  select.value = gltf.animations.length ? '0' : '-1';
  setAnimation(gltf.animations.length ? 0 : -1);
  if (state.surface) {
    $('level').value = String(state.surface.level);
    $('levelText').textContent = String(state.surface.level);
  }
  frameCamera(gltf.scene);
  applyToggles();
  applyFalseColour();
  message('');
  updateStats();
  if (state.surface) {
    state.errors = measureLevels(state.surface);
    updateStats();
  }
  state.ready = true;
}

// Input.
$('level').addEventListener('input', () => {
  $('levelText').textContent = $('level').value;
  $('level').dataset.asked = $('level').value;
  if (!state.surface) return;
  try {
    state.surface.setLevel(Number($('level').value));
    applyToggles();
    applyFalseColour();
    message('');
  } catch (e) {
    message(e.message);
  }
  updateStats();
});
$('animation').addEventListener('change', () => setAnimation(Number($('animation').value)));
$('play').addEventListener('click', () => {
  state.playing = !state.playing;
  $('play').textContent = state.playing ? 'Pause' : 'Play';
});
$('time').addEventListener('input', () => {
  state.playing = false;
  $('play').textContent = 'Play';
  if (state.mixer) state.mixer.setTime(Number($('time').value));
});
$('cage').addEventListener('change', applyToggles);
$('wireframe').addEventListener('change', () => { applyToggles(); if (state.falseColour) applyFalseColour(); });
$('falseColour').addEventListener('change', () => { state.falseColour = $('falseColour').checked; applyFalseColour(); });
// Adaptive level of detail: each frame, every control face at the lowest
// level within the pixel tolerance of the slider's level for this camera.
// The false colour then shows each vertex's level (the finest of the
// triangles it is drawn in) instead of its displacement.
$('adaptive').addEventListener('change', () => {
  state.adaptive = $('adaptive').checked ? {} : null;
  $('falseColourText').textContent = state.adaptive ? 'level false colour' : 'displacement false colour';
  if (!state.adaptive && state.surface) {
    state.surface.clearView();
    applyToggles();
    applyFalseColour();
  }
  updateStats();
});
$('pixelError').addEventListener('input', () => { $('pixelErrorText').textContent = `${$('pixelError').value} px`; });
async function loadFile(file) {
  const bytes = await file.arrayBuffer();
  await load(bytes, file.name, bytes.byteLength);
}
$('file').addEventListener('change', (e) => { if (e.target.files[0]) loadFile(e.target.files[0]); });
window.addEventListener('dragover', (e) => { e.preventDefault(); $('drop').style.display = 'flex'; });
window.addEventListener('dragleave', () => { $('drop').style.display = 'none'; });
window.addEventListener('drop', (e) => {
  e.preventDefault();
  $('drop').style.display = 'none';
  if (e.dataTransfer.files[0]) loadFile(e.dataTransfer.files[0]);
});
window.addEventListener('resize', () => {
  camera.aspect = view.clientWidth / view.clientHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(view.clientWidth, view.clientHeight);
});

// The frame: the mixer moves the nodes, the scene's matrix update poses the
// surface (timed here), then three draws.
const clock = new THREE.Clock();
renderer.setAnimationLoop(() => {
  const dt = clock.getDelta();
  const t0 = performance.now();
  if (state.mixer && state.playing) {
    state.mixer.update(dt);
    if (state.action) {
      const time = state.action.time;
      $('time').value = String(time);
      $('timeText').textContent = `${time.toFixed(2)} s`;
    }
  }
  scene.updateMatrixWorld();
  if (state.adaptive && state.surface) {
    try {
      const pixelError = Number($('pixelError').value);
      state.surface.setView(camera, { pixelError, heightPx: renderer.domElement.height });
      state.adaptive.pixelError = pixelError;
      if (state.falseColour && state.colouredVersion !== state.surface.adaptiveVersionShown) applyFalseColour();
    } catch (e) {
      message(e.message);
      $('adaptive').checked = false;
      state.adaptive = null;
    }
  }
  const ms = performance.now() - t0;
  state.frameMs = state.frames ? 0.9 * state.frameMs + 0.1 * ms : ms;
  if (++state.frames % 30 === 0) updateStats();
  controls.update();
  renderer.render(scene, camera);
});

const asked = new URLSearchParams(location.search).get('rig');
if (asked) {
  fetch(asked).then((r) => {
    if (!r.ok) throw new Error(`${asked}: HTTP ${r.status}`);
    return r.arrayBuffer();
  }).then((bytes) => load(bytes, asked.split('/').pop(), bytes.byteLength))
    .catch((e) => { message(e.message); state.ready = true; state.error = e.message; });
} else {
  state.ready = true;
}
