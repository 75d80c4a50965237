// Strata's runtime in WebAssembly: the C++ runtime and rig reader the
// native tools use, compiled with Emscripten (js/wasm/build.sh) and wrapped
// through its C API (io/include/strata/strata.h).  No refinement, codec or
// skinning is written in JavaScript: a surface evaluated here equals
// strata-reconstruct's bit for bit in the bind pose and whenever the pose
// comes from the rig's own animation.
//
//   const strata = await StrataRuntime.load();          // finds dist/strata.wasm beside this package
//   const rig = strata.loadRig(bytesOfGlb);             // throws StrataError with the tools' one-line message
//   const surface = rig.createSurface();                // the recommended level
//   surface.setAnimationTime(0, 1.0);
//   const { positions, normals } = surface.evaluate();  // Float32Arrays, 3 per refined vertex
//   surface.dispose(); rig.dispose();

const isNode = typeof process !== 'undefined' && !!(process.versions && process.versions.node);

export class StrataError extends Error {
  constructor(message, code) {
    super(message);
    this.name = 'StrataError';
    this.code = code;
  }
}

const STATUS = ['ok', 'invalid argument', 'invalid data', 'i/o error', 'unsupported', 'out of memory'];

// The module's own folder: dist/ beside src/.
function defaultURL(name) {
  return new URL(`../dist/${name}`, import.meta.url);
}

async function readBytes(url) {
  if (isNode && url.protocol === 'file:') {
    const { readFile } = await import('node:fs/promises');
    const { fileURLToPath } = await import('node:url');
    return new Uint8Array(await readFile(fileURLToPath(url)));
  }
  const response = await fetch(url);
  if (!response.ok) throw new StrataError(`${url}: HTTP ${response.status}`, 'io');
  return new Uint8Array(await response.arrayBuffer());
}

let shared = null;

export class StrataRuntime {
  /// Loads the WebAssembly module once per page (later calls share it).
  /// options.wasmURL / options.moduleURL: where strata.wasm and strata.mjs
  /// are, when not in dist/ beside this package; options.wasmBinary: the
  /// module's bytes, already fetched.
  static load(options = {}) {
    if (!shared || options.wasmURL || options.wasmBinary || options.moduleURL) {
      const promise = (async () => {
        const moduleURL = options.moduleURL ? new URL(options.moduleURL, import.meta.url) : defaultURL('strata.mjs');
        const wasmURL = options.wasmURL ? new URL(options.wasmURL, import.meta.url) : defaultURL('strata.wasm');
        const [{ default: factory }, wasmBinary] = await Promise.all([
          import(moduleURL.href),
          options.wasmBinary ? Promise.resolve(new Uint8Array(options.wasmBinary)) : readBytes(wasmURL),
        ]);
        return new StrataRuntime(await factory({ wasmBinary }));
      })();
      if (options.wasmURL || options.wasmBinary || options.moduleURL) return promise;
      shared = promise;
    }
    return shared;
  }

  constructor(module) {
    this.module = module;
    this.version = module.UTF8ToString(module._strata_version());
  }

  // Heap helpers.  Views are made after every call: the heap may grow.
  u8() { return this.module.HEAPU8; }
  f32(ptr, count) { return new Float32Array(this.module.HEAPU8.buffer, ptr, count); }
  u32(ptr, count) { return new Uint32Array(this.module.HEAPU8.buffer, ptr, count); }
  alloc(bytes) {
    const ptr = this.module._malloc(Math.max(4, bytes));
    if (!ptr) throw new StrataError('out of memory', 'out of memory');
    return ptr;
  }
  free(ptr) { if (ptr) this.module._free(ptr); }
  check(status, what) {
    if (status === 0) return;
    const message = this.module.UTF8ToString(this.module._strata_last_error());
    throw new StrataError(what ? `${what}: ${message}` : message, STATUS[status] || `status ${status}`);
  }
  // Calls fn(ptr) with `count` elements of 4 bytes of scratch, returning a copy as Type.
  withScratch(Type, count, fn) {
    const bytes = count * Type.BYTES_PER_ELEMENT;
    const ptr = this.alloc(Math.max(bytes, 4));
    try {
      fn(ptr);
      return new Type(this.module.HEAPU8.buffer.slice(ptr, ptr + bytes));
    } finally {
      this.free(ptr);
    }
  }

  /// A rig from the bytes of a .glb (or of a .gltf with every buffer
  /// embedded).  `name` prefixes error messages.
  loadRig(bytes, name = 'rig') {
    const data = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
    const binary = data.length >= 4 && data[0] === 0x67 && data[1] === 0x6c && data[2] === 0x54 && data[3] === 0x46;
    const m = this.module;
    const src = this.alloc(data.length);
    const out = this.alloc(4);
    try {
      this.u8().set(data, src);
      const status = m._strata_rig_load_memory(src, data.length, binary ? 1 : 0, out);
      if (status !== 0) {
        // The runtime names bytes in memory "rig.glb (memory)": use the caller's name.
        const message = m.UTF8ToString(m._strata_last_error()).replace(/^rig\.(glb|gltf) \(memory\)/, name);
        throw new StrataError(message.startsWith(name) ? message : `${name}: ${message}`, STATUS[status]);
      }
      return new StrataRig(this, this.u32(out, 1)[0]);
    } finally {
      this.free(src);
      this.free(out);
    }
  }
}

export class StrataRig {
  constructor(runtime, handle) {
    this.runtime = runtime;
    this.handle = handle;
    const m = runtime.module;
    this.recommendedLevel = m._strata_rig_recommended_level(handle);
    this.scheme = m._strata_rig_scheme(handle) === 1 ? 'smooth' : 'linear';
    this.controlVertexCount = m._strata_rig_control_vertex_count(handle) >>> 0;
    this.jointCount = m._strata_rig_joint_count(handle) >>> 0;
    this.animationCount = m._strata_rig_animation_count(handle) >>> 0;
  }
  animationName(index) {
    const ptr = this.runtime.module._strata_rig_animation_name(this.handle, index);
    return ptr ? this.runtime.module.UTF8ToString(ptr) : null;
  }
  /// The glTF node of skin joint `joint`.
  jointNode(joint) { return this.runtime.module._strata_rig_joint_node(this.handle, joint); }
  /// Joint `joint`'s inverse bind matrix (16 floats, column-major).
  inverseBindMatrix(joint) {
    const r = this.runtime;
    return r.withScratch(Float32Array, 16, (ptr) =>
      r.check(r.module._strata_rig_joint_inverse_bind(this.handle, joint, ptr)));
  }
  /// A surface at `level` (-1: the recommended one), displaced, in the bind pose.
  createSurface(level = -1) {
    const r = this.runtime;
    const out = r.alloc(4);
    try {
      r.check(r.module._strata_surface_create(this.handle, level, out));
      return new StrataSurface(r, r.u32(out, 1)[0], this);
    } finally {
      r.free(out);
    }
  }
  dispose() {
    if (this.handle) this.runtime.module._strata_rig_destroy(this.handle);
    this.handle = 0;
  }
}

export class StrataSurface {
  constructor(runtime, handle, rig) {
    this.runtime = runtime;
    this.handle = handle;
    const m = runtime.module;
    this.vertexCount = m._strata_surface_vertex_count(handle) >>> 0;
    this.triangleCount = m._strata_surface_triangle_count(handle) >>> 0;
    this.jointCount = rig ? rig.jointCount : 0;
    this.frame = 0;         // heap: positions then normals of the refined vertices
    this.joints = 0;        // heap: joint matrices
  }
  triangles() {
    const r = this.runtime;
    return r.withScratch(Uint32Array, this.triangleCount * 3, (ptr) =>
      r.check(r.module._strata_surface_triangles(this.handle, ptr)));
  }
  /// The bind pose: the control positions as stored.
  setBindPose() {
    this.runtime.check(this.runtime.module._strata_surface_set_bind_pose(this.handle));
  }
  /// The rig's animation `animation` at `time` seconds (-1: the nodes' rest pose).
  setAnimationTime(animation, time) {
    this.runtime.check(this.runtime.module._strata_surface_set_animation_time(this.handle, animation, time));
  }
  /// Skin matrices (world * inverse bind, 16 floats each, column-major), one per joint.
  setJointMatrices(matrices) {
    const r = this.runtime;
    const count = this.jointCount;
    if (matrices.length !== count * 16)
      throw new StrataError(`setJointMatrices: ${matrices.length / 16} matrices for ${count} joints`, 'invalid argument');
    if (!this.joints) this.joints = r.alloc(count * 64);
    r.f32(this.joints, count * 16).set(matrices);
    r.check(r.module._strata_surface_set_joint_matrices(this.handle, this.joints, count));
  }
  /// The current pose's displaced positions and normals (3 floats per
  /// refined vertex; new arrays unless `into` gives them).
  evaluate(into = {}) {
    const r = this.runtime;
    const n = this.vertexCount * 3;
    if (!this.frame) this.frame = r.alloc(n * 8);
    r.check(r.module._strata_surface_evaluate(this.handle, this.frame, this.frame + n * 4));
    const positions = into.positions || new Float32Array(n);
    const normals = into.normals || new Float32Array(n);
    positions.set(r.f32(this.frame, n));
    normals.set(r.f32(this.frame + n * 4, n));
    return { positions, normals };
  }
  /// A box that holds the current pose's surface at every level, uniform
  /// and adaptive: { min: [x, y, z], max: [x, y, z] } (for culling and
  /// picking without reading the frame).
  bounds() {
    const r = this.runtime;
    const box = r.withScratch(Float32Array, 6, (ptr) =>
      r.check(r.module._strata_surface_bounds(this.handle, ptr, ptr + 12)));
    return { min: Array.from(box.subarray(0, 3)), max: Array.from(box.subarray(3, 6)) };
  }
  /// Each refined vertex's displacement along its normal (model units).
  displacements() {
    const r = this.runtime;
    return r.withScratch(Float32Array, this.vertexCount, (ptr) =>
      r.check(r.module._strata_surface_displacements(this.handle, ptr)));
  }
  /// This surface laid out for drawing (StrataRenderMesh).
  createRenderMesh(rig) {
    return renderMesh(this.runtime, (out) => this.runtime.module._strata_render_mesh_create(rig.handle, this.handle, out));
  }
  /// Adaptive level of detail: each control face at the lowest level within
  /// `pixelError` pixels of this surface's level, for a camera at `eye`
  /// looking at `target` ([x, y, z] each) with a vertical field of view in
  /// degrees and a viewport `heightPx` tall, in the current pose; faces of
  /// different levels are stitched without cracks.  Then
  /// adaptiveVertexCount, adaptiveTriangles(), adaptiveVertices() and
  /// evaluateAdaptive() give the frame.
  chooseLevels(eye, target, fovYDegrees, heightPx, pixelError = 1) {
    const r = this.runtime;
    const view = r.alloc(24);
    try {
      r.f32(view, 6).set([eye[0], eye[1], eye[2], target[0], target[1], target[2]]);
      r.check(r.module._strata_surface_choose_levels(this.handle, view, view + 12, fovYDegrees, heightPx, pixelError));
    } finally {
      r.free(view);
    }
    this.adaptiveVertexCount = r.module._strata_surface_adaptive_vertex_count(this.handle) >>> 0;
    this.adaptiveTriangleCount = r.module._strata_surface_adaptive_triangle_count(this.handle) >>> 0;
  }
  /// The adaptive frame's triangles (3 indices each, into its vertices).
  adaptiveTriangles() {
    const r = this.runtime;
    return r.withScratch(Uint32Array, this.adaptiveTriangleCount * 3, (ptr) =>
      r.check(r.module._strata_surface_adaptive_triangles(this.handle, ptr)));
  }
  /// Per adaptive triangle, the level it is drawn at (its quarter's).
  adaptiveTriangleLevels() {
    const r = this.runtime;
    return r.withScratch(Uint8Array, this.adaptiveTriangleCount, (ptr) =>
      r.check(r.module._strata_surface_adaptive_triangle_levels(this.handle, ptr)));
  }
  /// Per adaptive vertex, its refined vertex (an index into evaluate()'s).
  adaptiveVertices() {
    const r = this.runtime;
    return r.withScratch(Uint32Array, this.adaptiveVertexCount, (ptr) =>
      r.check(r.module._strata_surface_adaptive_vertices(this.handle, ptr)));
  }
  /// The adaptive frame's positions and normals (3 floats per vertex).
  evaluateAdaptive(into = {}) {
    const r = this.runtime;
    const n = (this.adaptiveVertexCount || 0) * 3;
    if (n > (this.adaptiveCapacity || 0)) {
      r.free(this.adaptiveFrame);
      this.adaptiveFrame = r.alloc(Math.max(n, 3) * 8);
      this.adaptiveCapacity = n;
    }
    r.check(r.module._strata_surface_evaluate_adaptive(this.handle, this.adaptiveFrame, this.adaptiveFrame + n * 4));
    const positions = into.positions || new Float32Array(n);
    const normals = into.normals || new Float32Array(n);
    positions.set(r.f32(this.adaptiveFrame, n));
    normals.set(r.f32(this.adaptiveFrame + n * 4, n));
    return { positions, normals };
  }
  /// Changes whenever the adaptive frame's vertices and triangles do (a
  /// choice that keeps the levels drawn keeps it).
  adaptiveVersion() {
    return this.runtime.module._strata_surface_adaptive_version(this.handle) >>> 0;
  }
  /// The current adaptive frame laid out for drawing, from `uniform` (this
  /// surface's createRenderMesh): the same parts and attributes, each vertex
  /// with its grid point's value at this surface's level; the adaptive
  /// frame's vertices first.  Its evaluate() fills it from the adaptive
  /// frame, and throws once the levels change (make another).
  createAdaptiveRenderMesh(uniform) {
    return renderMesh(this.runtime,
      (out) => this.runtime.module._strata_render_mesh_create_adaptive(uniform.handle, this.handle, out));
  }
  dispose() {
    const r = this.runtime;
    if (this.handle) r.module._strata_surface_destroy(this.handle);
    r.free(this.frame);
    r.free(this.joints);
    r.free(this.adaptiveFrame);
    this.handle = this.frame = this.joints = this.adaptiveFrame = 0;
  }
}

// A render mesh from a C API call that writes its handle to `out`.
function renderMesh(runtime, create) {
  const out = runtime.alloc(4);
  try {
    runtime.check(create(out));
    return new StrataRenderMesh(runtime, runtime.u32(out, 1)[0]);
  } finally {
    runtime.free(out);
  }
}

/// One vertex per (refined vertex, refined corner value); the first
/// surface.vertexCount are the refined vertices in strata-reconstruct's
/// order, seam copies follow; parts are contiguous index ranges.
export class StrataRenderMesh {
  constructor(runtime, handle) {
    this.runtime = runtime;
    this.handle = handle;
    const m = runtime.module;
    this.vertexCount = m._strata_render_mesh_vertex_count(handle) >>> 0;
    this.indexCount = m._strata_render_mesh_index_count(handle) >>> 0;
    this.frame = 0;
  }
  indices() {
    const r = this.runtime;
    return r.withScratch(Uint32Array, this.indexCount, (ptr) =>
      r.check(r.module._strata_render_mesh_indices(this.handle, ptr)));
  }
  refinedVertices() {
    const r = this.runtime;
    return r.withScratch(Uint32Array, this.vertexCount, (ptr) =>
      r.check(r.module._strata_render_mesh_refined_vertices(this.handle, ptr)));
  }
  parts() {
    const r = this.runtime;
    const count = r.module._strata_render_mesh_part_count(this.handle) >>> 0;
    const parts = [];
    for (let i = 0; i < count; ++i) {
      const raw = r.withScratch(Int32Array, 5, (ptr) => r.check(r.module._strata_render_mesh_part(this.handle, i, ptr)));
      parts.push({ firstIndex: raw[0] >>> 0, indexCount: raw[1] >>> 0, mesh: raw[2], primitive: raw[3], material: raw[4],
        flat: r.module._strata_render_mesh_part_flat(this.handle, i) !== 0 });
    }
    return parts;
  }
  attributes() {
    const r = this.runtime;
    const m = r.module;
    const count = m._strata_render_mesh_attribute_count(this.handle) >>> 0;
    const out = [];
    for (let i = 0; i < count; ++i) {
      const name = m.UTF8ToString(m._strata_render_mesh_attribute_name(this.handle, i));
      const components = m._strata_render_mesh_attribute_components(this.handle, i);
      const array = r.withScratch(Float32Array, this.vertexCount * components, (ptr) =>
        r.check(m._strata_render_mesh_attribute(this.handle, i, ptr)));
      out.push({ name, components, array });
    }
    return out;
  }
  /// The surface's current pose into `positions` and `normals` (Float32Arrays
  /// of 3 * vertexCount).
  evaluate(surface, positions, normals) {
    const r = this.runtime;
    const n = this.vertexCount * 3;
    if (!this.frame) this.frame = r.alloc(n * 8);
    r.check(r.module._strata_render_mesh_evaluate(this.handle, surface.handle, this.frame, this.frame + n * 4));
    positions.set(r.f32(this.frame, n));
    if (normals) normals.set(r.f32(this.frame + n * 4, n));
  }
  dispose() {
    if (this.handle) this.runtime.module._strata_render_mesh_destroy(this.handle);
    this.runtime.free(this.frame);
    this.handle = this.frame = 0;
  }
}
