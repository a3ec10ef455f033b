// Validate a GLB/glTF file with the Khronos glTF-Validator and print the JSON report to stdout.
// Usage: node gltf_validate.mjs <file.glb>
// Exit code: 0 when the report has no errors, 1 when it has errors, 2 on usage/IO problems.
// process.exitCode is set instead of calling process.exit(), which can cut a piped report off.
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

async function main() {
  const path = process.argv[2];
  if (!path) {
    process.stderr.write("usage: node gltf_validate.mjs <file.glb>\n");
    process.exitCode = 2;
    return;
  }
  let buf;
  try {
    buf = await readFile(path);
  } catch (e) {
    process.stderr.write(`cannot read ${path}: ${e.message}\n`);
    process.exitCode = 2;
    return;
  }
  const report = await validator.validateBytes(new Uint8Array(buf), {
    maxIssues: 0,
    writeTimestamp: false,
  });
  process.stdout.write(JSON.stringify(report, null, 2) + "\n");
  process.exitCode = report.issues.numErrors > 0 ? 1 : 0;
}

main().catch((e) => {
  process.stderr.write(`validator failed: ${e && e.stack ? e.stack : e}\n`);
  process.exitCode = 2;
});
