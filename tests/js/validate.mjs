#!/usr/bin/env node
// Validates glb files with the Khronos glTF validator and prints one JSON report per file
// (errors, warnings, infos, the first messages, draw calls, triangles).
// Usage: node validate.mjs FILE.glb...   Exit code 3 if any file has errors or warnings, 0 if
// none has; any other code means the validator itself failed.
import { createRequire } from 'module';
import fs from 'fs';
import path from 'path';
const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

let failed = false;
for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    // Every unsupported extension and instanced node is an info; the report keeps its totals
    // only while the issues fit.
    maxIssues: 1000,
  });
  const issues = report.issues;
  if (issues.numErrors > 0 || issues.numWarnings > 0) failed = true;
  console.log(JSON.stringify({
    file,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    infos: issues.numInfos,
    messages: issues.messages.slice(0, 20).map((m) => `${m.code} ${m.pointer ?? ''} ${m.message}`),
    drawCalls: report.info?.drawCallCount,
    triangles: report.info?.totalTriangleCount,
    vertices: report.info?.totalVertexCount,
  }));
}
process.exit(failed ? 3 : 0);
