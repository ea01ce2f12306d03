// three.js (npm three, its GLTFLoader) loading each .gltf given. GLTFLoader has no MSFT_lod: it builds the scene's
// node tree, which holds the finest level only (the lower levels are reached through the extension). Node has no
// image decoder, so createImageBitmap is stood in for by one that reads a PNG's size (the texture is then present,
// with its size, but not decoded). Prints per file, as JSON, the meshes in the scene: vertex count, material,
// texture (width x height), base colour, vertex colours, world bounds; or the error the loader gave.
//   node tools/engine_three.cjs FILE.gltf...   (modules from NODE_PATH, else .venv/node/node_modules)
const path = require("path");
const { pathToFileURL } = require("url");
const inline = require("./gltf_inline.cjs");

globalThis.self ??= globalThis;   // ImageBitmapLoader fetches through self
globalThis.ProgressEvent ??= class ProgressEvent extends Event {   // FileLoader reports progress with it
  constructor(type, init = {}) { super(type); Object.assign(this, init); }
};
globalThis.createImageBitmap = async (blob) => {
  const png = Buffer.from(await blob.arrayBuffer());
  return { width: png.readUInt32BE(16), height: png.readUInt32BE(20), close() {} };
};

(async () => {
  const modules = process.env.NODE_PATH ? process.env.NODE_PATH.split(path.delimiter)[0]
    : path.join(__dirname, "..", ".venv", "node", "node_modules");   // make test's npm line
  const at = (p) => pathToFileURL(path.join(modules, p)).href;
  const THREE = await import(at("three/build/three.module.js"));
  const { GLTFLoader } = await import(at("three/examples/jsm/loaders/GLTFLoader.js"));
  const out = [];
  for (const file of process.argv.slice(2)) {
    try {
      const gltf = await new Promise((resolve, reject) =>
        new GLTFLoader().parse(JSON.stringify(inline(file)), "", resolve, reject));
      gltf.scene.updateMatrixWorld(true);
      const meshes = [];
      gltf.scene.traverse((o) => {
        if (!o.isMesh) return;
        const box = new THREE.Box3().setFromObject(o);
        const map = o.material.map;
        meshes.push({
          name: o.name, vertices: o.geometry.attributes.position.count, material: o.material.name,
          texture: Boolean(map && map.image), texture_size: map && map.image ? [map.image.width, map.image.height] : null,
          colour: o.material.color.toArray(), vertex_colours: Boolean(o.geometry.attributes.color),
          min: box.min.toArray(), max: box.max.toArray(),
        });
      });
      out.push({ file, meshes });
    } catch (e) {
      out.push({ file, error: `${e && e.name}: ${String(e && e.message).slice(-300)}` });
    }
  }
  console.log(JSON.stringify(out, null, 1));
})();
