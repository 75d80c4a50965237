// Strata's layered displacement in three.js: a GLTFLoader plugin.
//
//   import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
//   import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
//   import { StrataLoaderPlugin } from 'strata-layered/three';
//
//   const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);   // and a DRACOLoader
//   loader.register((parser) => new StrataLoaderPlugin(parser, { level: 'recommended' }));
//   const gltf = await loader.loadAsync('rig.glb');
//   scene.add(gltf.scene);                        // the refined, displaced surface
//   const mixer = new THREE.AnimationMixer(gltf.scene);
//   mixer.clipAction(gltf.animations[0]).play();  // drives it, as it drives any glTF
//
// For every file that carries the layer (the STRATA_layered_displacement
// extension, or a format-version 1-4 rig's extras), the loaded scene holds a
// StrataSurfaceMesh in place of the control meshes: the same C++ runtime as
// the native tools (WebAssembly, runtime.mjs) refines the cage to the level,
// displaces it and skins it with the matrices of the nodes three.js animates.
// The cage meshes stay in the scene, hidden (StrataSurfaceMesh.cage).  The
// first `refinedVertexCount` vertices of the surface's `position` attribute
// are the refined vertices in the order strata-reconstruct writes them to
// .obj and .ply; the copies a UV seam needs follow (`refinedVertex` maps every
// vertex to its refined one).  The geometry draws `drawnVertexCount` vertices
// and `drawnIndexCount` indices (its drawRange); an adaptive geometry's
// buffers may hold room past them.
//
// Adaptive level of detail: surface.setView(camera, { pixelError: 1,
// heightPx: renderer.domElement.height }) before each render draws each
// control face at the lowest level within the pixel tolerance of the
// surface's level for that camera (crack-free, textured as at the full
// level); clearView() or setLevel() draws one level everywhere again.
//
// A file whose layer no longer matches its control mesh (a tool changed the
// mesh after the bake) is refused: loadAsync rejects with the runtime's
// one-line cause, never a wrong surface.  Options:
//   level:    a number 0..6 or 'recommended' (default)
//   runtime:  a StrataRuntime (or its promise); default StrataRuntime.load()
//   name:     the file's name in error messages (default 'the glTF file')
import {
  Box3, BufferAttribute, BufferGeometry, DynamicDrawUsage, Matrix4, Mesh, MeshStandardMaterial, Sphere,
  StaticDrawUsage, Vector3,
} from 'three';
import { StrataError, StrataRuntime } from './runtime.mjs';

export const STRATA_LAYERED_DISPLACEMENT = 'STRATA_layered_displacement';

// A .glb rebuilt from what GLTFLoader kept of it: its JSON text and BIN chunk.
function glbBytes(json, body) {
  const text = new TextEncoder().encode(json);
  const jsonLength = (text.length + 3) & ~3;
  const binLength = body ? (body.byteLength + 3) & ~3 : 0;
  const total = 12 + 8 + jsonLength + (body ? 8 + binLength : 0);
  const out = new Uint8Array(total);
  const view = new DataView(out.buffer);
  view.setUint32(0, 0x46546c67, true);
  view.setUint32(4, 2, true);
  view.setUint32(8, total, true);
  view.setUint32(12, jsonLength, true);
  view.setUint32(16, 0x4e4f534a, true);
  out.set(text, 20);
  out.fill(0x20, 20 + text.length, 20 + jsonLength);
  if (body) {
    const at = 20 + jsonLength;
    view.setUint32(at, binLength, true);
    view.setUint32(at + 4, 0x004e4942, true);
    out.set(new Uint8Array(body), at + 8);
  }
  return out;
}

function base64(bytes) {
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

// The file as the runtime reads it: a .glb as it was, a .gltf with its
// external buffers and images embedded (the runtime reads no other file).
async function fileBytes(parser) {
  const binary = parser.extensions && parser.extensions.KHR_binary_glTF;
  const json = JSON.parse(JSON.stringify(parser.json));
  const external = (uri) => typeof uri === 'string' && !uri.startsWith('data:');
  if (binary && !(json.buffers || []).some((b) => external(b.uri)) && !(json.images || []).some((i) => external(i.uri)))
    return glbBytes(binary.content, binary.body);
  const path = parser.options.path || '';
  const fetchBytes = async (uri) => {
    const url = new URL(uri, new URL(path, globalThis.location ? globalThis.location.href : 'file:///'));
    const response = await fetch(url);
    if (!response.ok) throw new StrataError(`${uri}: HTTP ${response.status}`, 'i/o error');
    return new Uint8Array(await response.arrayBuffer());
  };
  for (const [i, b] of (json.buffers || []).entries())
    if (external(b.uri) || (b.uri === undefined && binary))
      b.uri = `data:application/octet-stream;base64,${base64(new Uint8Array(await parser.loadBuffer(i)))}`;
  for (const image of json.images || [])
    if (external(image.uri))
      image.uri = `data:${image.mimeType || 'application/octet-stream'};base64,${base64(await fetchBytes(image.uri))}`;
  return new TextEncoder().encode(JSON.stringify(json));
}

function carriesLayer(json) {
  if ((json.extensionsUsed || []).includes(STRATA_LAYERED_DISPLACEMENT)) return true;
  return (json.meshes || []).some((m) => m.extras && typeof m.extras === 'object' && m.extras.strata);
}

const ATTRIBUTE_NAMES = { TEXCOORD_0: 'uv', TEXCOORD_1: 'uv1', TEXCOORD_2: 'uv2', TEXCOORD_3: 'uv3', COLOR_0: 'color' };

/// The refined, displaced, skinned surface of a rig: a Mesh whose geometry
/// the runtime rewrites whenever the nodes it is skinned to move (checked
/// as the scene updates its matrices, so an AnimationMixer drives it with no
/// further call), with one material group per glTF primitive.
export class StrataSurfaceMesh extends Mesh {
  /// materialFor(part): the material of a part ({ mesh, primitive, material, flat }).
  constructor(runtime, rig, nodes, materialFor, cage, level) {
    super(new BufferGeometry());
    this.isStrataSurfaceMesh = true;
    this.name = 'Strata surface';
    this.runtime = runtime;
    this.rig = rig;
    this.nodes = nodes;        // Object3D per skin joint
    this.cage = cage;          // the control meshes, hidden
    this.inverseBind = [];
    for (let j = 0; j < rig.jointCount; ++j) this.inverseBind.push(new Matrix4().fromArray(rig.inverseBindMatrix(j)));
    // Per-frame scratch, made once: the skin matrices, those last applied,
    // and whether the surface shows the nodes' pose (not the rig's own).
    this.jointMatrices = new Float32Array(rig.jointCount * 16);
    this.lastJointMatrices = new Float32Array(rig.jointCount * 16);
    this.posedByNodes = false;
    this.toScene = new Matrix4();
    this.jointScratch = new Matrix4();
    this.viewScratch = new Matrix4();
    this.eyeScratch = new Vector3();
    this.targetScratch = new Vector3();
    this.surface = null;
    this.renderMesh = null;
    this.adaptiveMesh = null;
    this.setLevel(level);
    // Parts are the glTF primitives: the same at every level.
    const materials = this.parts.map(materialFor);
    this.material = materials.length === 1 ? materials[0] : materials;
  }

  /// Rebuilds the surface at `level` (a number, or 'recommended').
  setLevel(level) {
    const wanted = level === 'recommended' || level === undefined || level === null ? -1 : Number(level);
    const surface = this.rig.createSurface(wanted);
    let renderMesh;
    try {
      renderMesh = surface.createRenderMesh(this.rig);
    } catch (e) {
      surface.dispose();
      throw e;
    }
    this.dropView();
    if (this.renderMesh) this.renderMesh.dispose();
    if (this.surface) this.surface.dispose();
    this.surface = surface;
    this.renderMesh = renderMesh;
    this.level = wanted < 0 ? this.rig.recommendedLevel : wanted;
    this.showLayout(renderMesh);
    return this;
  }

  /// Adaptive level of detail for `camera` (a PerspectiveCamera): each
  /// control face at the lowest level whose surface stays within
  /// `pixelError` pixels of this mesh's level on a viewport `heightPx` tall,
  /// in the current pose (the same C++ as strata-reconstruct --view), with
  /// neighbours stitched without cracks and textures mapped as at the full
  /// level.  Call it before each render; the geometry is rebuilt only when
  /// the levels change.  Returns { vertices, triangles } drawn.  Then the
  /// first `refinedVertexCount` vertices of the geometry are the adaptive
  /// frame's (`refinedVertex` maps every vertex to its frame vertex).
  /// setLevel() or clearView() draws the uniform level again.
  setView(camera, { pixelError = 1, heightPx = 1080 } = {}) {
    if (!camera || !camera.isPerspectiveCamera)
      throw new StrataError('setView: a PerspectiveCamera is needed', 'invalid argument');
    camera.updateMatrixWorld();
    this.updateMatrixWorld();
    // The camera in the surface's own space (the rig's model space).
    const toModel = this.viewScratch.copy(this.matrixWorld).invert();
    const eye = this.eyeScratch.setFromMatrixPosition(camera.matrixWorld);
    const target = this.targetScratch.set(0, 0, -1).applyMatrix4(camera.matrixWorld);
    eye.applyMatrix4(toModel);
    target.applyMatrix4(toModel);
    // The lens as drawn: zoom narrows the field of view.
    const fov = (2 * Math.atan(Math.tan((camera.fov * Math.PI) / 360) / (camera.zoom || 1)) * 180) / Math.PI;
    this.surface.chooseLevels(eye.toArray(), target.toArray(), fov, heightPx, pixelError);
    const version = this.surface.adaptiveVersion();
    if (!this.adaptiveMesh || version !== this.adaptiveVersionShown) {
      const layout = this.surface.createAdaptiveRenderMesh(this.renderMesh);
      if (this.adaptiveMesh) this.adaptiveMesh.dispose();
      this.adaptiveMesh = layout;
      this.adaptiveVersionShown = version;
      this.showLayout(layout);
    }
    return { vertices: this.refinedVertexCount, triangles: this.surface.adaptiveTriangleCount };
  }

  /// Back to the uniform level after setView.
  clearView() {
    if (!this.adaptiveMesh) return this;
    this.dropView();
    this.showLayout(this.renderMesh);
    return this;
  }

  dropView() {
    if (this.adaptiveMesh) this.adaptiveMesh.dispose();
    this.adaptiveMesh = null;
    this.adaptiveVersionShown = -1;
  }

  // `layout` (the uniform or the adaptive render mesh) as the geometry, in
  // the current pose.  An adaptive layout goes into the current geometry's
  // buffers where they hold it (an adaptive frame changes levels often as a
  // character moves; new buffers would be new GPU buffers each time), else
  // into new ones with room to grow.
  showLayout(layout) {
    const reuse = layout === this.adaptiveMesh;
    this.refinedVertexCount = reuse ? this.surface.adaptiveVertexCount : this.surface.vertexCount;
    const n = layout.vertexCount;
    const indices = layout.indices();
    const attributes = layout.attributes().map((a) => ({ ...a, name: ATTRIBUTE_NAMES[a.name] || a.name.toLowerCase() }));
    const parts = layout.parts();
    const old = this.geometry;
    const room = old.userData.strataRoom;
    const fits = reuse && room && n <= room.vertices && indices.length <= room.indices &&
      attributes.length + 2 === Object.keys(old.attributes).length &&
      attributes.every((a) => old.attributes[a.name] && old.attributes[a.name].itemSize === a.components);
    let geometry = old;
    if (fits) {
      for (const a of attributes) {
        const b = old.attributes[a.name];
        b.array.set(a.array);
        b.clearUpdateRanges();
        b.addUpdateRange(0, a.array.length);
        b.needsUpdate = true;
      }
      old.index.array.set(indices);
      old.index.clearUpdateRanges();
      old.index.addUpdateRange(0, indices.length);
      old.index.needsUpdate = true;
      old.clearGroups();
    } else {
      const grow = reuse ? 1.5 : 1;
      const vertices = Math.ceil(grow * n), count = Math.ceil(grow * indices.length);
      geometry = new BufferGeometry();
      geometry.userData.strataRoom = { vertices, indices: count };
      for (const name of ['position', 'normal'])
        geometry.setAttribute(name, new BufferAttribute(new Float32Array(3 * vertices), 3).setUsage(DynamicDrawUsage));
      for (const a of attributes) {
        const array = new Float32Array(vertices * a.components);
        array.set(a.array);
        geometry.setAttribute(a.name, new BufferAttribute(array, a.components).setUsage(reuse ? DynamicDrawUsage : StaticDrawUsage));
      }
      const index = new Uint32Array(count);
      index.set(indices);
      geometry.setIndex(new BufferAttribute(index, 1).setUsage(reuse ? DynamicDrawUsage : StaticDrawUsage));
    }
    parts.forEach((p, i) => geometry.addGroup(p.firstIndex, p.indexCount, i));
    geometry.setDrawRange(0, indices.length);
    this.drawnVertexCount = n;
    this.drawnIndexCount = indices.length;
    this.refinedVertex = layout.refinedVertices();
    this.parts = parts;
    if (geometry !== old) {
      this.geometry = geometry;
      old.dispose();
    }
    this.posedByNodes = false;
    this.update(true);
  }

  /// The geometry's bounding box and sphere: the runtime's box of the
  /// current pose (it holds the surface at every level, uniform and
  /// adaptive), so three culls and picks the surface where it is drawn.
  /// Called with every frame written.
  updateBounds() {
    const g = this.geometry;
    const box = this.surface.bounds();
    if (!g.boundingBox) g.boundingBox = new Box3();
    if (!g.boundingSphere) g.boundingSphere = new Sphere();
    g.boundingBox.min.fromArray(box.min);
    g.boundingBox.max.fromArray(box.max);
    g.boundingBox.getBoundingSphere(g.boundingSphere);
  }

  /// Poses the surface from its nodes' current world matrices (relative
  /// to its parent, the glTF scene) and rewrites the geometry if they moved
  /// since it was last posed by them.  `force`: rewrite anyway.
  update(force = false) {
    if (!this.surface) return;
    if (this.rig.jointCount > 0) {
      this.toScene.identity();
      if (this.parent) this.toScene.copy(this.parent.matrixWorld).invert();
      const m = this.jointScratch;
      for (let j = 0; j < this.rig.jointCount; ++j) {
        m.multiplyMatrices(this.toScene, this.nodes[j].matrixWorld).multiply(this.inverseBind[j]);
        this.jointMatrices.set(m.elements, 16 * j);
      }
      if (!force && this.posedByNodes && this.lastJointMatrices.every((v, i) => v === this.jointMatrices[i])) return;
      this.lastJointMatrices.set(this.jointMatrices);
      this.surface.setJointMatrices(this.jointMatrices);
      this.writeFrame();
      this.posedByNodes = true;
    } else if (force) {
      this.writeFrame();
    }
  }

  /// Poses from the rig's own animation at `time` seconds (-1: the nodes'
  /// rest pose), as strata-reconstruct --anim/--time does (bit for bit),
  /// instead of from the nodes, until the nodes move again.
  setAnimationTime(animation, time) {
    this.surface.setAnimationTime(animation, time);
    this.writeFrame();
    this.posedByNodes = false;
  }

  /// The bind pose (the control positions as stored, what
  /// strata-reconstruct writes without --anim), until the nodes move again.
  setBindPose() {
    this.surface.setBindPose();
    this.writeFrame();
    this.posedByNodes = false;
  }

  // The surface's current pose into the geometry.
  writeFrame() {
    const g = this.geometry;
    (this.adaptiveMesh || this.renderMesh).evaluate(this.surface, g.attributes.position.array, g.attributes.normal.array);
    for (const a of [g.attributes.position, g.attributes.normal]) {
      a.clearUpdateRanges();
      a.addUpdateRange(0, 3 * this.drawnVertexCount);
      a.needsUpdate = true;
    }
    this.updateBounds();
  }

  updateMatrixWorld(force) {
    super.updateMatrixWorld(force);
    // The scene's update reaches this mesh after its siblings (it is added
    // last), so the nodes' matrices are this frame's.
    this.update();
  }

  dispose() {
    this.dropView();
    if (this.renderMesh) this.renderMesh.dispose();
    if (this.surface) this.surface.dispose();
    if (this.rig) this.rig.dispose();
    this.geometry.dispose();
    this.renderMesh = this.surface = this.rig = null;
  }
}

export class StrataLoaderPlugin {
  constructor(parser, options = {}) {
    this.name = STRATA_LAYERED_DISPLACEMENT;
    this.parser = parser;
    this.options = options;
  }

  async afterRoot(result) {
    const parser = this.parser;
    if (!carriesLayer(parser.json)) return;
    const runtime = await (this.options.runtime || StrataRuntime.load());
    const name = this.options.name || 'the glTF file';
    let rig;
    try {
      rig = runtime.loadRig(await fileBytes(parser), name);
    } catch (e) {
      throw e instanceof StrataError ? e : new StrataError(String(e && e.message || e), 'invalid data');
    }
    try {
      // The three.js mesh of every glTF primitive, and the node of every joint.
      const primitiveMesh = new Map();
      result.scene.traverse((o) => {
        const a = parser.associations.get(o);
        if (o.isMesh && a && a.meshes !== undefined && a.primitives !== undefined)
          primitiveMesh.set(`${a.meshes}/${a.primitives}`, o);
      });
      const nodes = [];
      for (let j = 0; j < rig.jointCount; ++j) nodes.push(await parser.getDependency('node', rig.jointNode(j)));
      // Materials per part, as three.js set them up for the cage.
      // GLTFLoader shades a primitive without NORMAL flat, which every
      // control mesh is: the surface is flat only where the rig says its
      // capture was (part.flat), so the cage's material is copied with the
      // surface's own shading where the two differ.
      const cage = [];
      const shaded = new Map();
      const materialFor = (part) => {
        const mesh = primitiveMesh.get(`${part.mesh}/${part.primitive}`);
        if (mesh && !cage.includes(mesh)) cage.push(mesh);
        const material = mesh ? mesh.material : new MeshStandardMaterial();
        if (Boolean(material.flatShading) === part.flat) return material;
        const key = `${material.uuid}/${part.flat}`;
        if (!shaded.has(key)) {
          const copy = material.clone();
          copy.flatShading = part.flat;
          shaded.set(key, copy);
        }
        return shaded.get(key);
      };
      const surface = new StrataSurfaceMesh(runtime, rig, nodes, materialFor, cage, this.options.level ?? 'recommended');
      for (const c of cage) c.visible = false;
      result.scene.add(surface);
      result.scene.updateMatrixWorld(true);
      surface.update(true);  // posed by its nodes in the scene now (and its bounds)
      result.userData = result.userData || {};
      result.userData.strata = surface;
    } catch (e) {
      rig.dispose();
      throw e;
    }
  }
}

export { StrataRuntime, StrataError };
