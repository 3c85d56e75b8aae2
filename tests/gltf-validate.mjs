// Validates GLB files with the Khronos glTF validator (npm `gltf-validator`) and fails on any
// error or warning (issue 13: the bar is 0 and 0). Usage: node gltf-validate.mjs FILE.glb [...]
// Prints the first 20 messages with severity error or warning; infos and hints are counted only.
import { readFile } from 'node:fs/promises';
import { basename } from 'node:path';
import validator from 'gltf-validator';

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node gltf-validate.mjs FILE.glb [FILE.glb ...]');
  process.exit(2);
}
let failed = 0;
for (const file of files) {
  const data = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(data, {
    uri: basename(file),
    maxIssues: 1000,
    externalResourceFunction: () => Promise.reject(new Error('external resources are not allowed')),
  });
  const { numErrors, numWarnings, numInfos, numHints, messages } = report.issues;
  console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos, ${numHints} hints`);
  let shown = 0;
  for (const m of messages) {
    if (m.severity <= 1 && shown++ < 20) {
      console.log(`  ${m.severity === 0 ? 'ERROR' : 'warning'} ${m.code} at ${m.pointer ?? ''}: ${m.message}`);
    }
  }
  if (numErrors > 0 || numWarnings > 0) failed++;
}
if (failed > 0) {
  console.error(`${failed} of ${files.length} files have validation errors or warnings`);
  process.exit(1);
}
