// node tests/web/validate.js FILE: the Khronos glTF validator's report of FILE (.glb or .gltf) as JSON on stdout.
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

const file = process.argv[2];
const bytes = new Uint8Array(fs.readFileSync(file));
validator.validateBytes(bytes, {
  uri: path.basename(file),
  maxIssues: 0,
  externalResourceFunction: (uri) => Promise.reject(new Error(`no external resources: ${uri}`)),
}).then((report) => console.log(JSON.stringify(report)), (error) => {
  console.error(String(error));
  process.exit(1);
});
