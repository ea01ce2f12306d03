// A .gltf with its external resources (.bin, images) turned into data: URIs (glTF 2.0 §3.6.1.1, "Data URI"), so an
// engine running in Node without a browser's fetch of files reads the whole asset from one string.
const fs = require("fs");
const path = require("path");

const TYPES = { ".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".bin": "application/octet-stream" };

module.exports = function inline(file) {
  const doc = JSON.parse(fs.readFileSync(file, "utf8"));
  for (const item of [...(doc.buffers || []), ...(doc.images || [])]) {
    if (item.uri && !item.uri.startsWith("data:")) {
      const bytes = fs.readFileSync(path.join(path.dirname(file), decodeURIComponent(item.uri)));
      const type = TYPES[path.extname(item.uri).toLowerCase()] || "application/octet-stream";
      item.uri = `data:${type};base64,${bytes.toString("base64")}`;
    }
  }
  return doc;
};
