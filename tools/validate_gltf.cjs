// The Khronos glTF validator (npm gltf-validator) on one .gltf/.glb file: prints its report as JSON, exits 0
// when it has no error. Its external resources (.bin, images) are read from beside the file.
//   node tools/validate_gltf.cjs FILE.gltf     (GLTF_VALIDATOR: the package's folder, if not on NODE_PATH)
const fs = require("fs");
const path = require("path");
const validator = require(process.env.GLTF_VALIDATOR ? path.resolve(process.env.GLTF_VALIDATOR) : "gltf-validator");

const file = process.argv[2];
validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
  uri: path.basename(file),
  externalResourceFunction: (uri) => new Promise((resolve, reject) => {
    fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
      err ? reject(err.toString()) : resolve(new Uint8Array(data)));
  }),
}).then((report) => {
  console.log(JSON.stringify(report, null, 1));
  process.exit(report.issues.numErrors ? 1 : 0);
}, (error) => {
  console.error(error);
  process.exit(2);
});
