// Validates binary glTF files with the Khronos glTF validator and prints one JSON line per file:
// {"file", "errors", "warnings", "infos", "messages"} (the messages of severity error or warning).
// Usage: node validate.mjs FILE.glb [FILE.glb ...]; exits 1 when a file has errors.
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

let failed = false;
for (const file of process.argv.slice(2)) {
  const data = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(data, {
    uri: file,
    maxIssues: 0,
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri} not allowed`)),
  });
  const issues = report.issues;
  const messages = issues.messages.filter((m) => m.severity <= 1);
  console.log(JSON.stringify({
    file,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    infos: issues.numInfos,
    messages,
  }));
  failed ||= issues.numErrors > 0;
}
process.exit(failed ? 1 : 0);
