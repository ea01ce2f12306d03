// Babylon.js (npm babylonjs + babylonjs-loaders; NullEngine, no GPU) loading each .gltf given with MSFT_lod on, as its
// loader has it by default. Babylon loads MSFT_lod progressively: the coarsest level first, then each finer one in
// turn, disposing the one before; it does not switch on MSFT_screencoverage. Each level is caught by loading the
// file again with the extension's maxLODsToLoad = 1, 2, ... (it keeps the k coarsest levels, showing the k-th).
// Prints per file, as JSON, per stage (coarsest first) the meshes shown: vertex count, material, texture, albedo
// colour, first vertex colour, world bounds, the node's glTF extras; or the error the loader threw.
//   node tools/engine_babylon.cjs FILE.gltf...   (modules from NODE_PATH, else .venv/node/node_modules)
module.paths.push(require("path").join(__dirname, "..", ".venv", "node", "node_modules"));   // make test's npm line
global.BABYLON = require("babylonjs");
require("babylonjs-loaders");
const inline = require("./gltf_inline.cjs");

BABYLON.Logger.LogLevels = BABYLON.Logger.ErrorLogLevel;   // stdout is the report
const engine = new BABYLON.NullEngine();

function shown(scene) {
  return scene.meshes.filter((m) => m.isEnabled() && m.getTotalVertices() > 0).map((m) => {
    m.computeWorldMatrix(true);
    const box = m.getBoundingInfo().boundingBox;
    const colours = m.getVerticesData(BABYLON.VertexBuffer.ColorKind);
    const mat = m.material || {};
    return {
      name: m.name, vertices: m.getTotalVertices(), material: mat.name || null,
      texture: Boolean(mat.albedoTexture), albedo: mat.albedoColor ? mat.albedoColor.asArray() : null,
      first_colour: colours ? Array.from(colours.slice(0, 3)) : null,
      min: box.minimumWorld.asArray(), max: box.maximumWorld.asArray(),
      extras: (m.metadata && m.metadata.gltf && m.metadata.gltf.extras) || null,   // ExtrasAsMetadata
    };
  });
}

async function stage(doc, k) {
  const scene = new BABYLON.Scene(engine);
  try {
    await BABYLON.AppendSceneAsync("data:" + JSON.stringify(doc), scene, {
      pluginExtension: ".gltf", pluginOptions: { gltf: { extensionOptions: { MSFT_lod: { maxLODsToLoad: k } } } },
    });
    await scene.whenReadyAsync();
    return shown(scene);
  } finally {
    scene.dispose();
  }
}

(async () => {
  const out = [];
  for (const file of process.argv.slice(2)) {
    const doc = inline(file);
    const first = doc.nodes.find((n) => n.extensions && n.extensions.MSFT_lod);
    const levels = first ? first.extensions.MSFT_lod.ids.length + 1 : 1;
    const report = { file, stages: [] };
    try {
      for (let k = 1; k <= levels; k++) report.stages.push(await stage(doc, k));
    } catch (e) {
      report.error = `${e && e.name}: ${String(e && e.message).slice(-300)}`;
    }
    out.push(report);
  }
  console.log(JSON.stringify(out, null, 1));
})();
