// Validates a glTF/GLB file with the Khronos glTF-Validator (npm gltf-validator) and prints the report
// as JSON on stdout. Exit code: 0 when the report has no errors, warnings, infos or hints; 1 when it
// has any; 2 when the file cannot be read or validated at all.
//
// usage: node exporters/js/validate_gltf.mjs FILE.glb
// External resources (buffers, images) are resolved relative to the file; glint's GLBs have none.

import { readFile } from 'node:fs/promises';
import path from 'node:path';
import validator from 'gltf-validator';

const file = process.argv[2];
if (!file) {
  console.error('usage: node validate_gltf.mjs FILE.glb');
  process.exit(2);
}

try {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0, // report everything
    externalResourceFunction: (uri) =>
      readFile(path.resolve(path.dirname(file), decodeURIComponent(uri))).then((b) => new Uint8Array(b)),
  });
  console.log(JSON.stringify(report, null, 2));
  const i = report.issues;
  process.exit(i.numErrors + i.numWarnings + i.numInfos + i.numHints === 0 ? 0 : 1);
} catch (e) {
  console.error(`validate_gltf: cannot validate ${file}: ${e}`);
  process.exit(2);
}
