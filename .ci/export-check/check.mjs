// Checks an exported 3D Tiles tileset (or one GLB) with the ecosystem's own tools:
// every glTF content through the Khronos glTF validator, the tileset and every content through
// loaders.gl's 3D Tiles loader (as a loaders.gl client would parse them).
//
//   node .ci/export-check/check.mjs OUT/tileset.json   or   node check.mjs city.glb
//
// Prints one JSON line {contents, validator_errors, validator_warnings, loader_errors, messages}
// and exits 1 when any error was found. Installed by .ci/setup.sh (npm ci, pinned versions).
import fs from 'node:fs';
import path from 'node:path';
import validator from 'gltf-validator';
import {parse} from '@loaders.gl/core';
import {Tiles3DLoader} from '@loaders.gl/3d-tiles';

const target = process.argv[2];
if (!target) {
  console.error('usage: node check.mjs TILESET.json|FILE.glb');
  process.exit(2);
}
const summary = {contents: 0, validator_errors: 0, validator_warnings: 0, loader_errors: 0, messages: []};
const arrayBuffer = (file) => {
  const b = fs.readFileSync(file);
  return b.buffer.slice(b.byteOffset, b.byteOffset + b.byteLength);
};

async function checkGlb(file, asTileContent) {
  summary.contents += 1;
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: file,
    maxIssues: 100,
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
  });
  summary.validator_errors += report.issues.numErrors;
  summary.validator_warnings += report.issues.numWarnings;
  for (const m of report.issues.messages.filter((m) => m.severity <= 1).slice(0, 5)) {
    summary.messages.push(`${file}: ${m.code} ${m.message} at ${m.pointer}`);
  }
  if (asTileContent) {
    try {
      await parse(arrayBuffer(file), Tiles3DLoader, {'3d-tiles': {loadGLTF: true}, baseUri: file});
    } catch (e) {
      summary.loader_errors += 1;
      summary.messages.push(`${file}: loaders.gl: ${e.message}`);
    }
  }
}

if (target.endsWith('.json')) {
  const dir = path.dirname(target);
  let tileset;
  try {
    tileset = await parse(arrayBuffer(target), Tiles3DLoader, {'3d-tiles': {isTileset: true}, baseUri: target});
  } catch (e) {
    summary.loader_errors += 1;
    summary.messages.push(`${target}: loaders.gl: ${e.message}`);
  }
  // The contents as the tileset names them (the raw JSON: loaders.gl rewrites URIs).
  const raw = JSON.parse(fs.readFileSync(target, 'utf8'));
  const walk = async (tile) => {
    if (tile.content?.uri) {
      const file = path.join(dir, tile.content.uri);
      if (!fs.existsSync(file)) {
        summary.loader_errors += 1;
        summary.messages.push(`${file}: missing`);
      } else {
        await checkGlb(file, true);
      }
    }
    for (const child of tile.children ?? []) await walk(child);
  };
  await walk(raw.root);
  if (tileset && !tileset.root) {
    summary.loader_errors += 1;
    summary.messages.push(`${target}: loaders.gl found no root tile`);
  }
} else {
  await checkGlb(target, false);
}
console.log(JSON.stringify(summary));
process.exit(summary.validator_errors + summary.loader_errors > 0 ? 1 : 0);
