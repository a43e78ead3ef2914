#!/usr/bin/env node
// validate_gltf.mjs FILE.glb|FILE.gltf — runs the Khronos glTF-Validator (npm package
// `gltf-validator`, installed by `npm ci --prefix tools`) on one self-contained file and prints
// its JSON report on stdout. Exit status: 0 when the report has no errors, 1 when it has errors,
// 2 when the file cannot be read or the validator cannot run.
import { readFile } from "node:fs/promises";
import { basename } from "node:path";
import validator from "gltf-validator";

const file = process.argv[2];
if (!file) {
  console.error("usage: node tools/validate_gltf.mjs FILE.glb");
  process.exit(2);
}
try {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, {
    uri: basename(file),
    maxIssues: 0, // report every issue
    // A .glb from furbake export is self-contained: any external reference is a failure.
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri} in a self-contained file`)),
  });
  console.log(JSON.stringify(report, null, 2));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
} catch (e) {
  console.error(`validate_gltf.mjs: ${file}: ${e && e.message ? e.message : e}`);
  process.exit(2);
}
