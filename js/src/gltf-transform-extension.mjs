// STRATA_layered_displacement for glTF Transform (https://gltf-transform.dev):
// reads the layer into the document graph and writes it back, so that
// commands which follow references (copy, dedup, prune, resample, texture
// commands) keep the coded displacements and the map with the mesh they
// belong to.  The layer's own JSON travels unchanged; only its references
// (the accessor of coded per-vertex values, the map image) are renumbered.
//
// Commands that renumber or move the control mesh's vertices (reorder,
// weld, meshopt, draco, quantize) are carried too: on read, every vertex of
// the control mesh is tagged with its number in the baked mesh (the
// _STRATA_VERTEX attribute, which those commands carry along like any
// other), and the control mesh as read is kept aside.  On write, a control
// mesh that is still the one read loses the tag again; one that a command
// changed keeps it, and the layer gains `baked`: the control mesh as it
// was baked (accessors the commands never saw), from which Strata rebuilds
// the baked surface bit for bit, after checking that the tagged triangles
// are still the baked ones.  Commands that change the triangles (simplify,
// join) end in Strata's refusal with the cause
// (docs/STRATA_layered_displacement.md, "Carrying the layer").
import { Extension, ExtensionProperty, PropertyType } from '@gltf-transform/core';

export const STRATA_LAYERED_DISPLACEMENT = 'STRATA_layered_displacement';

/** The layer of one mesh: its JSON (references removed) and the properties it refers to. */
export class LayeredDisplacement extends ExtensionProperty {
  static EXTENSION_NAME = STRATA_LAYERED_DISPLACEMENT;

  init() {
    this.extensionName = STRATA_LAYERED_DISPLACEMENT;
    this.propertyType = 'LayeredDisplacement';
    this.parentTypes = [PropertyType.MESH];
  }

  getDefaults() {
    return Object.assign(super.getDefaults(), { definition: {}, vertices: null, map: null });
  }

  /** The layer's JSON without its accessor and image indices. */
  getDefinition() { return this.get('definition'); }
  setDefinition(definition) { return this.set('definition', definition); }

  /** The accessor of coded per-vertex values, or null. */
  getVertices() { return this.getRef('vertices'); }
  setVertices(accessor) { return this.setRef('vertices', accessor, { usage: 'OTHER' }); }

  /** The embedded map (a grey PNG), or null. */
  getMap() { return this.getRef('map'); }
  setMap(texture) { return this.setRef('map', texture); }
}

/** The map's image type while in a document (texture commands skip types they do not know). */
const MAP_MIME_TYPE = 'application/x-strata-displacement';

/** The attribute that numbers each control vertex in the baked mesh (low and high 16 bits). */
export const STRATA_VERTEX = '_STRATA_VERTEX';

const TRIANGLE_MODES = new Set([4, 5, 6]);

function isIdentityNode(nodeDef) {
  const same = (a, b) => !a || a.every((v, i) => v === b[i]);
  return same(nodeDef.matrix, [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]) && same(nodeDef.translation, [0, 0, 0]) &&
    same(nodeDef.rotation, [0, 0, 0, 1]) && same(nodeDef.scale, [1, 1, 1]);
}

// Whether every triangle primitive sits in the control mesh's space as
// stored (skinned, or on nodes without a transform): only then is the
// control mesh Strata welds a function of the stored accessors alone, which
// `baked` can hold bit for bit.
function storedInControlSpace(json) {
  const nodes = json.nodes || [];
  const parent = new Map();
  nodes.forEach((n, i) => (n.children || []).forEach((c) => parent.set(c, i)));
  return (json.meshes || []).every((mesh, m) => {
    const first = nodes.findIndex((n) => n.mesh === m);
    if (first < 0 || nodes[first].skin !== undefined) return true;
    for (let n = first, guard = 0; n !== undefined && guard <= nodes.length; n = parent.get(n), ++guard)
      if (!isIdentityNode(nodes[n])) return false;
    return true;
  });
}

// The map's UV set, as Strata reads it: texCoord of the map, none for
// per-vertex values without one, else 0.
function layerTexCoord(def) {
  const tex = def.displacementGeometryTexture;
  if (tex && Number.isInteger(tex.texCoord)) return tex.texCoord;
  return def.displacementVertices ? -1 : 0;
}

function sameArray(a, b) {
  if (!a || !b) return a === b;
  if (a.length !== b.length) return false;
  for (let i = 0; i < a.length; ++i) if (!Object.is(a[i], b[i])) return false;
  return true;
}

function floatArray(accessor) {
  return accessor && accessor.getComponentType() === 5126 && !accessor.getNormalized() ? accessor.getArray().slice() : null;
}

export class StrataLayeredDisplacement extends Extension {
  static EXTENSION_NAME = STRATA_LAYERED_DISPLACEMENT;
  extensionName = STRATA_LAYERED_DISPLACEMENT;
  prewriteTypes = [PropertyType.ACCESSOR];

  createLayeredDisplacement() {
    return new LayeredDisplacement(this.document.getGraph());
  }

  // Every triangle primitive of every mesh, in mesh and primitive order: the
  // parts Strata welds into the control mesh.
  _parts() {
    const parts = [];
    for (const mesh of this.document.getRoot().listMeshes())
      for (const prim of mesh.listPrimitives()) if (TRIANGLE_MODES.has(prim.getMode())) parts.push(prim);
    return parts;
  }

  read(context) {
    const json = context.jsonDoc.json;
    // Meshes that share one layer (the parts of one character) share one property.
    const shared = new Map();
    (json.meshes || []).forEach((meshDef, meshIndex) => {
      const def = meshDef.extensions && meshDef.extensions[STRATA_LAYERED_DISPLACEMENT];
      if (!def) return;
      const key = JSON.stringify(def);
      let layer = shared.get(key);
      if (!layer) {
        const definition = structuredClone(def);
        layer = this.createLayeredDisplacement();
        const vertices = definition.displacementVertices;
        if (vertices && Number.isInteger(vertices.accessor) && context.accessors[vertices.accessor]) {
          layer.setVertices(context.accessors[vertices.accessor]);
          delete vertices.accessor;
        }
        const texture = definition.displacementGeometryTexture;
        if (texture && Number.isInteger(texture.image) && context.textures[texture.image]) {
          // The map is data, not a picture: texture commands (resize, webp,
          // jpeg, ktx2) would resample or re-encode it lossily.  They skip
          // textures of a type they do not know, so it has one until write.
          const map = context.textures[texture.image];
          layer._mapMimeType = map.getMimeType();
          layer.setMap(map.setMimeType(MAP_MIME_TYPE));
          delete texture.image;
        }
        layer._baked = this._readBaked(context, definition);
        delete definition.baked;
        layer.setDefinition(definition);
        shared.set(key, layer);
      }
      context.meshes[meshIndex].setExtension(STRATA_LAYERED_DISPLACEMENT, layer);
    });
    if (shared.size === 1) this._tag([...shared.values()][0], json);
    return this;
  }

  // The control mesh the layer was baked on, as plain arrays: the `baked`
  // parts of a file another command already changed, else the parts as read.
  _readBaked(context, definition) {
    const baked = definition.baked;
    if (baked && Array.isArray(baked.parts)) {
      const acc = (i) => (Number.isInteger(i) ? context.accessors[i] : null);
      const parts = baked.parts.map((p) => ({
        mode: Number.isInteger(p.mode) ? p.mode : 4,
        position: floatArray(acc(p.POSITION)),
        indices: acc(p.indices) ? Uint32Array.from(acc(p.indices).getArray()) : null,
        texCoord: Number.isInteger(p.texCoord) ? floatArray(acc(p.texCoord)) : null,
      }));
      return parts.every((p) => p.position) ? { parts, fromFile: true } : null;
    }
    return { parts: null, fromFile: false };
  }

  // Numbers every vertex of every triangle primitive by its place in the
  // baked mesh (a file that already carries `baked` keeps its numbers).
  _tag(layer, json) {
    const state = layer._baked;
    if (!state) return;
    const prims = this._parts();
    if (state.fromFile) {
      if (!prims.every((p) => p.getAttribute(STRATA_VERTEX))) layer._baked = null;
      return;
    }
    const texCoord = layerTexCoord(layer.getDefinition());
    if (!storedInControlSpace(json) || prims.some((p) => !floatArray(p.getAttribute('POSITION')))) {
      layer._baked = null;
      return;
    }
    const buffer = this.document.getRoot().listBuffers()[0];
    let serial = 0;
    state.parts = prims.map((prim) => {
      const position = floatArray(prim.getAttribute('POSITION'));
      const uv = texCoord >= 0 ? prim.getAttribute(`TEXCOORD_${texCoord}`) : null;
      const count = position.length / 3;
      const ids = new Uint16Array(2 * count);
      for (let i = 0; i < count; ++i, ++serial) {
        ids[2 * i] = serial & 0xffff;
        ids[2 * i + 1] = serial >>> 16;
      }
      prim.setAttribute(STRATA_VERTEX, this.document.createAccessor().setType('VEC2').setArray(ids).setBuffer(buffer));
      return {
        mode: prim.getMode(),
        position,
        indices: prim.getIndices() ? Uint32Array.from(prim.getIndices().getArray()) : null,
        texCoord: floatArray(uv),
      };
    });
  }

  // Before the accessors are written: a control mesh the commands left
  // alone loses its tags; a changed one keeps them and gets `baked`.
  prewrite(_context, _type) {
    const layers = new Set(this.document.getRoot().listMeshes().map((m) => m.getExtension(STRATA_LAYERED_DISPLACEMENT)).filter(Boolean));
    for (const layer of layers) {
      for (const accessor of layer._bakedAccessors || []) accessor.dispose();
      layer._bakedAccessors = [];
      layer._bakedDef = null;
    }
    const prims = this._parts();
    const layer = layers.size === 1 ? [...layers][0] : null;
    const state = layer && layer._baked && layer._baked.parts ? layer._baked : null;
    // Draco and meshopt re-encode the mesh as it is written (Draco renumbers
    // and quantises it, meshopt may rotate triangles), after this check.
    const recoded = this.document.getRoot().listExtensionsUsed()
      .some((e) => e.extensionName === 'KHR_draco_mesh_compression' || e.extensionName === 'EXT_meshopt_compression');
    let unchanged = !state || state.fromFile || recoded ? false : prims.length === state.parts.length;
    if (unchanged) {
      const texCoord = layerTexCoord(layer.getDefinition());
      let serial = 0;
      unchanged = prims.every((prim, k) => {
        const part = state.parts[k];
        const ids = prim.getAttribute(STRATA_VERTEX);
        const count = part.position.length / 3;
        const same = prim.getMode() === part.mode && sameArray(floatArray(prim.getAttribute('POSITION')), part.position) &&
          sameArray(prim.getIndices() ? Uint32Array.from(prim.getIndices().getArray()) : null, part.indices) &&
          (texCoord < 0 || sameArray(floatArray(prim.getAttribute(`TEXCOORD_${texCoord}`)), part.texCoord));
        if (!same || (ids && ids.getCount() !== count)) return false;
        for (let i = 0; ids && i < count; ++i, ++serial) {
          const el = ids.getElement(i, []);
          if (el[0] + 65536 * el[1] !== serial) return false;
        }
        if (!ids) serial += count;
        return true;
      });
    }
    if (!state || unchanged) {
      for (const prim of prims) {
        const ids = prim.getAttribute(STRATA_VERTEX);
        if (!ids) continue;
        prim.setAttribute(STRATA_VERTEX, null);
        if (ids.listParents().every((p) => p.propertyType === PropertyType.ROOT)) ids.dispose();
      }
      return;
    }
    if (!prims.every((p) => p.getAttribute(STRATA_VERTEX))) return;  // a command dropped the tags: Strata refuses the file
    const buffer = this.document.getRoot().listBuffers()[0];
    const make = (type, array) => {
      const accessor = this.document.createAccessor().setType(type).setArray(array).setBuffer(buffer);
      layer._bakedAccessors.push(accessor);
      return accessor;
    };
    layer._bakedDef = state.parts.map((part) => ({
      mode: part.mode,
      POSITION: make('VEC3', part.position),
      indices: part.indices ? make('SCALAR', part.indices.every((i) => i < 65536) ? Uint16Array.from(part.indices) : part.indices) : null,
      texCoord: part.texCoord ? make('VEC2', part.texCoord) : null,
    }));
  }

  write(context) {
    const json = context.jsonDoc.json;
    this.document.getRoot().listMeshes().forEach((mesh) => {
      const layer = mesh.getExtension(STRATA_LAYERED_DISPLACEMENT);
      if (!layer) return;
      const def = structuredClone(layer.getDefinition());
      const vertices = layer.getVertices();
      if (vertices) {
        def.displacementVertices = def.displacementVertices || {};
        def.displacementVertices.accessor = context.accessorIndexMap.get(vertices);
      }
      const map = layer.getMap();
      if (map) {
        def.displacementGeometryTexture = def.displacementGeometryTexture || {};
        def.displacementGeometryTexture.image = context.imageIndexMap.get(map);
        const imageDef = json.images[def.displacementGeometryTexture.image];
        if (imageDef && imageDef.mimeType === MAP_MIME_TYPE) imageDef.mimeType = layer._mapMimeType || 'image/png';
      }
      if (layer._bakedDef) {
        const index = (a) => context.accessorIndexMap.get(a);
        def.baked = {
          parts: layer._bakedDef.map((p) => {
            const part = { mode: p.mode, POSITION: index(p.POSITION) };
            if (p.indices) part.indices = index(p.indices);
            if (p.texCoord) part.texCoord = index(p.texCoord);
            return part;
          }),
        };
      }
      const meshDef = json.meshes[context.meshIndexMap.get(mesh)];
      meshDef.extensions = meshDef.extensions || {};
      meshDef.extensions[STRATA_LAYERED_DISPLACEMENT] = def;
    });
    return this;
  }
}
