// Validates one glTF file with the Khronos glTF validator (npm gltf-validator) and prints its
// report as JSON. Usage: node validate.js FILE.glb   (run by ../blender_test.py)
const fs = require("fs");
const path = require("path");
const validator = require(path.join(__dirname, "node_modules", "gltf-validator"));

const file = process.argv[2];
validator
  .validateBytes(new Uint8Array(fs.readFileSync(file)), { uri: path.basename(file) })
  .then((report) => process.stdout.write(JSON.stringify(report)))
  .catch((error) => {
    console.error(`validate.js: ${file}: ${error}`);
    process.exit(1);
  });
