// STRATA_layered_displacement for glTF Transform (https://gltf-transform.dev):
// reads the layer into the document graph and writes it back, so that
// commands which follow references (copy, dedup, prune, resample, texture
// commands) keep the coded displacements and the map with the mesh they
// belong to.  The layer's own JSON travels unchanged; only its references
// (the accessor of coded per-vertex values, the map image) are renumbered.
// Commands that renumber or move the control mesh's vertices (reorder,
// meshopt, draco, quantize, simplify) cannot carry the values through: the
// layer records the control mesh it was baked on, and Strata refuses the
// file with the cause (docs/STRATA_layered_displacement.md).
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

export class StrataLayeredDisplacement extends Extension {
  static EXTENSION_NAME = STRATA_LAYERED_DISPLACEMENT;
  extensionName = STRATA_LAYERED_DISPLACEMENT;

  createLayeredDisplacement() {
    return new LayeredDisplacement(this.document.getGraph());
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
          layer.setMap(context.textures[texture.image]);
          delete texture.image;
        }
        layer.setDefinition(definition);
        shared.set(key, layer);
      }
      context.meshes[meshIndex].setExtension(STRATA_LAYERED_DISPLACEMENT, layer);
    });
    return this;
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
      }
      const meshDef = json.meshes[context.meshIndexMap.get(mesh)];
      meshDef.extensions = meshDef.extensions || {};
      meshDef.extensions[STRATA_LAYERED_DISPLACEMENT] = def;
    });
    return this;
  }
}
