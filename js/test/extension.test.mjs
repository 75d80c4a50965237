// The glTF Transform extension on its own: a mesh's layer keeps its coded
// values and its map through read, prune, dedup and write, with the
// references renumbered and the layer's other fields untouched.
import assert from 'node:assert/strict';
import test from 'node:test';
import { NodeIO } from '@gltf-transform/core';
import { dedup, prune } from '@gltf-transform/functions';
import { StrataLayeredDisplacement, STRATA_LAYERED_DISPLACEMENT } from '../src/gltf-transform-extension.mjs';

// A triangle whose layer refers to accessor 2 (8 coded bytes) and image 0,
// after an unused accessor that prune removes (so the indices must move).
function rigJson() {
  const bin = new Uint8Array(36 + 8 + 12 + 8 + 4);
  const f = new Float32Array(bin.buffer, 0, 9);
  f.set([0, 0, 0, 1, 0, 0, 0, 1, 0]);
  bin.set([1, 2, 3, 4, 5, 6, 7, 8], 36);
  bin.set([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a], 56);  // a PNG signature is all the image needs here
  const json = {
    asset: { version: '2.0', generator: 'Strata test' },
    extensionsUsed: [STRATA_LAYERED_DISPLACEMENT],
    buffers: [{ byteLength: bin.length }],
    bufferViews: [
      { buffer: 0, byteOffset: 0, byteLength: 36 },
      { buffer: 0, byteOffset: 36, byteLength: 8 },
      { buffer: 0, byteOffset: 44, byteLength: 12 },
      { buffer: 0, byteOffset: 56, byteLength: 8 },
    ],
    accessors: [
      { bufferView: 0, componentType: 5126, count: 3, type: 'VEC3', min: [0, 0, 0], max: [1, 1, 0] },
      { bufferView: 2, componentType: 5126, count: 3, type: 'SCALAR' },
      { bufferView: 1, componentType: 5121, count: 8, type: 'SCALAR' },
    ],
    images: [{ bufferView: 3, mimeType: 'image/png' }],
    meshes: [{
      primitives: [{ attributes: { POSITION: 0 } }],
      extensions: {
        [STRATA_LAYERED_DISPLACEMENT]: {
          displacementGeometryFactor: 0.5,
          displacementGeometryOffset: -1,
          scheme: 'smooth',
          recommendedLevel: 3,
          displacementVertices: { accessor: 2, level: 3, count: 45 },
          displacementGeometryTexture: { image: 0, encoding: 'png16', width: 4, height: 4, texCoord: 0 },
          control: { vertices: 3, triangles: 1, topology: '0123456789abcdef', positions: '0123456789abcdef',
                     shape: '0123456789abcdef' },
        },
      },
    }],
    nodes: [{ mesh: 0 }],
    scenes: [{ nodes: [0] }],
    scene: 0,
  };
  return { json, resources: { '@glb.bin': bin } };
}

test('the layer survives prune and dedup with its references renumbered', async () => {
  const io = new NodeIO().registerExtensions([StrataLayeredDisplacement]);
  const doc = await io.readJSON(rigJson());
  await doc.transform(dedup(), prune());
  const out = await io.writeJSON(doc, { format: 'glb' });
  const layer = out.json.meshes[0].extensions[STRATA_LAYERED_DISPLACEMENT];
  assert.ok(out.json.extensionsUsed.includes(STRATA_LAYERED_DISPLACEMENT));
  assert.ok(!(out.json.extensionsRequired || []).includes(STRATA_LAYERED_DISPLACEMENT));
  assert.equal(out.json.accessors.length, 2, 'the unused accessor is pruned, the layer\'s is kept');
  const acc = out.json.accessors[layer.displacementVertices.accessor];
  assert.equal(acc.componentType, 5121);
  assert.equal(acc.count, 8);
  const view = out.json.bufferViews[acc.bufferView];
  const bin = out.resources[out.json.buffers[0].uri || '@glb.bin'];
  const bytes = bin.slice((view.byteOffset || 0) + (acc.byteOffset || 0), (view.byteOffset || 0) + (acc.byteOffset || 0) + 8);
  assert.deepEqual([...bytes], [1, 2, 3, 4, 5, 6, 7, 8]);
  assert.equal(out.json.images.length, 1, 'the map image no material uses is kept');
  assert.equal(layer.displacementGeometryTexture.image, 0);
  assert.equal(layer.scheme, 'smooth');
  assert.equal(layer.control.topology, '0123456789abcdef');
  assert.equal(layer.displacementVertices.count, 45);
});

test('without the extension registered, glTF Transform drops the layer whole', async () => {
  const io = new NodeIO();
  const doc = await io.readJSON(rigJson());
  const out = await io.writeJSON(doc, { format: 'glb' });
  assert.equal(out.json.meshes[0].extensions, undefined);
  assert.ok(!(out.json.extensionsUsed || []).includes(STRATA_LAYERED_DISPLACEMENT));
});

// The triangle with indices, for the carrying tests.
function indexedRigJson() {
  const { json, resources } = rigJson();
  const bin = new Uint8Array(resources['@glb.bin'].length + 8);
  bin.set(resources['@glb.bin']);
  new Uint16Array(bin.buffer, resources['@glb.bin'].length, 3).set([0, 1, 2]);
  json.buffers[0].byteLength = bin.length;
  json.bufferViews.push({ buffer: 0, byteOffset: resources['@glb.bin'].length, byteLength: 6 });
  json.accessors.push({ bufferView: 4, componentType: 5123, count: 3, type: 'SCALAR' });
  json.meshes[0].primitives[0].indices = 3;
  delete json.meshes[0].extensions[STRATA_LAYERED_DISPLACEMENT].displacementGeometryTexture;
  json.images = [];
  json.bufferViews[3].byteLength = 8;
  return { json, resources: { '@glb.bin': bin } };
}

test('a control mesh no command changed is written without tags or a baked copy', async () => {
  const io = new NodeIO().registerExtensions([StrataLayeredDisplacement]);
  const doc = await io.readJSON(indexedRigJson());
  assert.ok(doc.getRoot().listMeshes()[0].listPrimitives()[0].getAttribute('_STRATA_VERTEX'), 'tagged on read');
  const out = await io.writeJSON(doc, { format: 'glb' });
  assert.deepEqual(Object.keys(out.json.meshes[0].primitives[0].attributes), ['POSITION']);
  assert.equal(out.json.meshes[0].extensions[STRATA_LAYERED_DISPLACEMENT].baked, undefined);
});

test('a renumbered and moved control mesh keeps its tags and gains the baked mesh', async () => {
  const io = new NodeIO().registerExtensions([StrataLayeredDisplacement]);
  const doc = await io.readJSON(indexedRigJson());
  // What reorder and quantize do: permute the vertices (2, 0, 1), move them a little.
  const prim = doc.getRoot().listMeshes()[0].listPrimitives()[0];
  const order = [2, 0, 1];
  for (const semantic of prim.listSemantics()) {
    const a = prim.getAttribute(semantic);
    const moved = a.clone();
    order.forEach((from, to) => moved.setElement(to, a.getElement(from, []).map((v) => (semantic === 'POSITION' ? v + 1e-4 : v))));
    prim.setAttribute(semantic, moved);
  }
  prim.setIndices(prim.getIndices().clone().setArray(new Uint16Array([1, 2, 0])));
  const out = await io.writeJSON(doc, { format: 'glb' });
  const layer = out.json.meshes[0].extensions[STRATA_LAYERED_DISPLACEMENT];
  assert.equal(layer.baked.parts.length, 1);
  const read = (index) => {
    const acc = out.json.accessors[index];
    const view = out.json.bufferViews[acc.bufferView];
    const bin = out.resources[out.json.buffers[view.buffer].uri || '@glb.bin'];
    const Ctor = { 5126: Float32Array, 5123: Uint16Array, 5125: Uint32Array }[acc.componentType];
    const size = { SCALAR: 1, VEC2: 2, VEC3: 3 }[acc.type];
    const stride = view.byteStride || size * Ctor.BYTES_PER_ELEMENT;
    const data = new DataView(bin.buffer, bin.byteOffset + (view.byteOffset || 0) + (acc.byteOffset || 0));
    const get = { 5126: (o) => data.getFloat32(o, true), 5123: (o) => data.getUint16(o, true), 5125: (o) => data.getUint32(o, true) }[acc.componentType];
    const values = [];
    for (let i = 0; i < acc.count; ++i)
      for (let k = 0; k < size; ++k) values.push(get(i * stride + k * Ctor.BYTES_PER_ELEMENT));
    return values;
  };
  const part = layer.baked.parts[0];
  assert.equal(part.mode, 4);
  assert.deepEqual(read(part.POSITION), [0, 0, 0, 1, 0, 0, 0, 1, 0], 'the positions as read, exactly');
  assert.deepEqual(read(part.indices), [0, 1, 2]);
  // Each vertex's tag names the baked vertex it came from.
  const tags = read(out.json.meshes[0].primitives[0].attributes._STRATA_VERTEX);
  assert.deepEqual(tags, [2, 0, 0, 0, 1, 0]);
});
