#!/usr/bin/env node
// validate_gltf.mjs FILE.glb|FILE.gltf [FILE…] — runs the Khronos glTF-Validator (npm package
// `gltf-validator`, installed by `npm ci --prefix tools`) on self-contained files and prints its
// JSON report on stdout: for one file the report itself, for several a JSON array of their
// reports in argument order (one node process for a batch: the validator's start-up dominates a
// small file). Exit status: 0 when no report has errors, 1 when one has errors, 2 when a file
// cannot be read or the validator cannot run.
import { readFile } from "node:fs/promises";
import { basename } from "node:path";
import validator from "gltf-validator";

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error("usage: node tools/validate_gltf.mjs FILE.glb [FILE.glb …]");
  process.exit(2);
}

async function validate(file) {
  const bytes = new Uint8Array(await readFile(file));
  return validator.validateBytes(bytes, {
    uri: basename(file),
    maxIssues: 0, // report every issue
    // A .glb from furbake export is self-contained: any external reference is a failure.
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri} in a self-contained file`)),
  });
}

const reports = [];
for (const file of files) {
  try {
    reports.push(await validate(file));
  } catch (e) {
    console.error(`validate_gltf.mjs: ${file}: ${e && e.message ? e.message : e}`);
    process.exit(2);
  }
}
console.log(JSON.stringify(files.length === 1 ? reports[0] : reports, null, 2));
// Not process.exit: it would cut a long report short on a pipe (stdout is written asynchronously).
process.exitCode = reports.some((r) => r.issues.numErrors > 0) ? 1 : 0;
