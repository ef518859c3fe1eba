#!/usr/bin/env node
// Runs the Khronos glTF validator (npm gltf-validator, the reference
// implementation) on each file given and prints its counts and messages.
// Exit status: 0 when every file has 0 errors and 0 warnings, 1 otherwise,
// 2 on a missing file or an unusable installation. docs/report.md.
'use strict';
const fs = require('fs');
const path = require('path');
let validator;
try {
  validator = require('gltf-validator');
} catch (e) {
  console.error('error: gltf-validator is not installed: run `npm ci` in ' + __dirname +
                ' (tools/install_deps.sh does)');
  process.exit(2);
}

async function validateFile(file) {
  const data = new Uint8Array(fs.readFileSync(file));
  const dir = path.dirname(file);
  return validator.validateBytes(data, {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: (uri) => new Promise((resolve, reject) => {
      fs.readFile(path.join(dir, decodeURIComponent(uri)), (err, d) => {
        if (err) reject(err.toString()); else resolve(new Uint8Array(d));
      });
    }),
  });
}

(async () => {
  const files = process.argv.slice(2);
  if (files.length === 0) {
    console.error('usage: validate_gltf.js FILE.glb|FILE.gltf ...');
    process.exit(2);
  }
  let failed = false;
  for (const file of files) {
    if (!fs.existsSync(file)) {
      console.error('error: ' + file + ': no such file');
      process.exit(2);
    }
    const report = await validateFile(file);
    const issues = report.issues;
    console.log(file + ': ' + issues.numErrors + ' errors, ' + issues.numWarnings +
                ' warnings, ' + issues.numInfos + ' infos, ' + issues.numHints + ' hints' +
                ' (validator ' + report.validatorVersion + ')');
    for (const m of issues.messages) {
      const severity = ['error', 'warning', 'info', 'hint'][m.severity];
      console.log('  ' + severity + ' ' + m.code + ' ' + (m.pointer || '') + ': ' + m.message);
    }
    if (issues.numErrors > 0 || issues.numWarnings > 0) failed = true;
  }
  process.exit(failed ? 1 : 0);
})().catch((e) => {
  console.error('error: ' + e);
  process.exit(2);
});
