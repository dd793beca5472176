// citywalk's exported 3D Tiles in a real client: CesiumJS in headless Chromium (Debian's
// chromium, WebGL in software through SwiftShader), served from a local static server, with
// nothing fetched from outside (no Ion, imagery, terrain or sky). The camera is citywalk's: a
// pose in the scene's local frame taken to the globe by the tileset's root transform, with
// citywalk's vertical field of view.
//
//   node .ci/cesium-check/view.mjs OUT/ --size 640x360 --camera X,Y,Z,YAW,PITCH --shot cesium.png
//   node .ci/cesium-check/view.mjs OUT/ --size 640x360 --path walk.path --times cesium.json
//
// --shot writes the frame of --camera once its tiles are loaded, over a flat magenta background
// (255, 0, 255): every other pixel is a building. --path plays a citywalk camera path (.path,
// see scenes/src/camera_path.rs), one pose per frame: at each pose the tiles are loaded (not
// timed), then --repeat frames (default 3) are drawn and finished, and their median is that
// pose's frame time. --sse sets the tileset's maximumScreenSpaceError (default 16, Cesium's own;
// the --shot comparison uses 1 so that the finest tiles are drawn, as citywalk's frame).
//
// Prints one JSON line {canvas, fov_deg, errors, external_requests, shot?, frames?} and exits 1
// when the page, the console or the tileset reported an error or anything outside was asked for.
// Installed by .ci/setup.sh (npm ci, pinned versions; Debian's chromium).
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import {fileURLToPath} from 'node:url';
import {chromium} from 'playwright-core';

const here = path.dirname(fileURLToPath(import.meta.url));
const cesiumBuild = path.join(here, 'node_modules', 'cesium', 'Build', 'Cesium');
const BACKGROUND = [1, 0, 1];

function usage(message) {
  console.error(`${message}\nusage: node view.mjs TILESET_DIR --size WxH [--camera X,Y,Z,YAW,PITCH --shot OUT.png] [--path FILE.path --times OUT.json] [--fov-y DEG] [--sse N] [--repeat N]`);
  process.exit(2);
}

const args = {fovY: 60, sse: 16, repeat: 3, limitMs: 60000};
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; i++) {
  const value = () => argv[++i] ?? usage(`${argv[i - 1]} needs a value`);
  switch (argv[i]) {
    case '--size': [args.width, args.height] = value().split('x').map(Number); break;
    case '--camera': args.camera = value().split(',').map(Number); break;
    case '--shot': args.shot = value(); break;
    case '--path': args.path = value(); break;
    case '--times': args.times = value(); break;
    case '--fov-y': args.fovY = Number(value()); break;
    case '--sse': args.sse = Number(value()); break;
    case '--repeat': args.repeat = Number(value()); break;
    default:
      if (argv[i].startsWith('--') || args.dir) usage(`unexpected ${argv[i]}`);
      args.dir = argv[i];
  }
}
if (!args.dir || !(args.width > 0 && args.height > 0)) usage('a tileset folder and --size are needed');
if (args.camera && (args.camera.length !== 5 || args.camera.some((v) => !Number.isFinite(v)))) usage('--camera X,Y,Z,YAW,PITCH');
if (!!args.camera !== !!args.shot) usage('--camera and --shot go together');
if (!args.camera && !args.path) usage('nothing to do: give --camera/--shot or --path');

// A citywalk .path file: `pose x y z yaw pitch` lines, `fov_y_deg` before them.
function readPath(file) {
  const poses = [];
  let fovY;
  for (const line of fs.readFileSync(file, 'utf8').split('\n')) {
    const words = line.replace(/#.*/, '').trim().split(/\s+/);
    if (words[0] === 'pose') poses.push(words.slice(1, 6).map(Number));
    if (words[0] === 'fov_y_deg') fovY = Number(words[1]);
  }
  return {poses, fovY};
}

const tilesetJson = JSON.parse(fs.readFileSync(path.join(args.dir, 'tileset.json'), 'utf8'));
const transform = tilesetJson.root.transform ?? [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];

const PAGE = `<!doctype html><html><head><meta charset="utf-8">
<script>window.CESIUM_BASE_URL = '/cesium/';</script>
<script src="/cesium/Cesium.js"></script>
<link href="/cesium/Widgets/widgets.css" rel="stylesheet">
<style>html, body, #view { margin: 0; padding: 0; width: 100%; height: 100%; overflow: hidden; }
.cesium-widget-credits { display: none !important; }</style>
</head><body><div id="view"></div><script src="/page.js"></script></body></html>`;

const TYPES = {
  '.js': 'text/javascript', '.mjs': 'text/javascript', '.json': 'application/json', '.css': 'text/css',
  '.glb': 'model/gltf-binary', '.wasm': 'application/wasm', '.png': 'image/png', '.jpg': 'image/jpeg',
  '.svg': 'image/svg+xml', '.html': 'text/html', '.xml': 'application/xml', '.ktx2': 'image/ktx2',
};

// Static files: / the page, /page.js, /cesium/* Cesium's build, /tiles/* the tileset.
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(new URL(req.url, 'http://localhost').pathname);
  let file;
  if (url === '/') {
    res.writeHead(200, {'content-type': 'text/html'});
    res.end(PAGE);
    return;
  } else if (url === '/page.js') file = path.join(here, 'page.js');
  else if (url.startsWith('/cesium/')) file = path.join(cesiumBuild, url.slice('/cesium/'.length));
  else if (url.startsWith('/tiles/')) file = path.join(args.dir, url.slice('/tiles/'.length));
  const root = file && (file.startsWith(cesiumBuild) || file.startsWith(path.resolve(args.dir)) || file === path.join(here, 'page.js'));
  fs.readFile(root ? file : '', (err, body) => {
    if (err) {
      res.writeHead(404);
      res.end();
      return;
    }
    res.writeHead(200, {'content-type': TYPES[path.extname(file)] ?? 'application/octet-stream'});
    res.end(body);
  });
});
args.dir = path.resolve(args.dir);
await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
const base = `http://127.0.0.1:${server.address().port}`;

const userData = fs.mkdtempSync(path.join(process.env.TMPDIR ?? '/tmp', 'citywalk-chromium-'));
const browser = await chromium.launchPersistentContext(userData, {
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  headless: true,
  viewport: {width: args.width, height: args.height},
  deviceScaleFactor: 1,
  args: [
    '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
  ],
});
const summary = {canvas: null, fov_deg: null, errors: [], external_requests: []};
try {
  const page = browser.pages()[0] ?? (await browser.newPage());
  await page.route('**/*', (route) => {
    const url = route.request().url();
    if (url.startsWith(base)) return route.continue();
    summary.external_requests.push(url);
    return route.abort();
  });
  page.on('console', (m) => {
    if (m.type() === 'error') summary.errors.push(`console: ${m.text()}`);
  });
  page.on('pageerror', (e) => summary.errors.push(`page: ${e.message}`));
  page.on('requestfailed', (r) => {
    if (r.url().startsWith(base)) summary.errors.push(`request failed: ${r.url()}`);
  });
  page.on('response', (r) => {
    if (r.status() >= 400) summary.errors.push(`HTTP ${r.status()}: ${r.url()}`);
  });
  await page.goto(`${base}/`);
  await page.waitForFunction(() => window.citywalk && window.Cesium);
  const path_ = args.path ? readPath(args.path) : null;
  const fovYDeg = path_?.fovY ?? args.fovY;
  Object.assign(summary, await page.evaluate((o) => window.citywalk.setup(o), {
    tileset: `${base}/tiles/tileset.json`, transform, fovYDeg, background: BACKGROUND,
    maximumScreenSpaceError: args.camera ? 1 : args.sse,
  }));
  if (args.camera) {
    const {settled, png} = await page.evaluate(([p, l]) => window.citywalk.shot(p, l), [args.camera, args.limitMs]);
    fs.writeFileSync(args.shot, Buffer.from(png.slice(png.indexOf(',') + 1), 'base64'));
    summary.shot = {file: args.shot, ...settled};
    if (!settled.loaded) summary.errors.push(`tiles still loading after ${args.limitMs} ms`);
  }
  if (args.path) {
    const frames = await page.evaluate(([p, s, r, l]) => window.citywalk.play(p, s, r, l),
      [path_.poses, args.sse, args.repeat, args.limitMs]);
    const ms = frames.map((f) => f.ms).sort((a, b) => a - b);
    const at = (q) => ms[Math.min(ms.length - 1, Math.floor(q * ms.length))];
    summary.frames = {
      count: ms.length, sse: args.sse, repeat: args.repeat,
      median_ms: at(0.5), p95_ms: at(0.95), mean_ms: ms.reduce((a, b) => a + b, 0) / ms.length,
      settle_ms_total: frames.reduce((a, f) => a + f.settle_ms, 0),
    };
    if (args.times) fs.writeFileSync(args.times, JSON.stringify({...summary.frames, frames}, null, 1));
  }
  summary.errors.push(...(await page.evaluate(() => window.citywalk.errors)));
} catch (e) {
  summary.errors.push(`view.mjs: ${e.stack ?? e}`);
} finally {
  await browser.close();
  server.close();
  fs.rmSync(userData, {recursive: true, force: true});
}
console.log(JSON.stringify(summary));
process.exit(summary.errors.length || summary.external_requests.length ? 1 : 0);
