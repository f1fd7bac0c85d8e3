// The npm package vtex-synth (packages/vtex-synth) as a user gets it: packed by `npm pack` (whose
// prepack copies in the wrapper and every model's module), its tarball installed into a fresh
// project with no registry, imported by its name through its exports map. The README's example,
// taken from the README itself, renders every model's tiles in Node and a tile onto a canvas in
// Chromium, byte for byte the tiles of a live `vtex serve`; tsc --strict accepts a typed consumer
// and refuses a mistyped one on exactly its wrong lines.
// Needs: scripts/build-wasm, target/release/vtex (or VTEX_BIN), `npm ci` in tests/npm (TypeScript)
// and in client-web (playwright-core), Debian's chromium and python3.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync, spawnSync } from 'node:child_process';
import { cpSync, mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { pathToFileURL } from 'node:url';
import { moduleFile } from '../../client-web/src/shared/vtex-synth.js';
import { fetchServerTile, launchBrowser, startServer, staticServer } from '../browser/lib.mjs';
import { MODELS, ROOT, modulePath } from '../wasm/modules.mjs';

const PACKAGE = join(ROOT, 'packages', 'vtex-synth');
const README = readFileSync(join(PACKAGE, 'README.md'), 'utf8');
const TSC = join(ROOT, 'tests', 'npm', 'node_modules', '.bin', 'tsc');
/** How the README's example names the texture it renders; the test puts a real one there. */
const PLACEHOLDER = 'http://localhost:8080/api/v1/textures/TEXTURE_ID';

let work;
/** The consumer: a fresh project with the tarball installed. */
let app;
/** What `npm pack --json` said of the tarball. */
let packed;
let server;
let textures;

before(async () => {
  work = mkdtempSync(join(tmpdir(), 'vtex-npm-'));
  const said = execFileSync('npm', ['pack', '--json', '--pack-destination', work], { cwd: PACKAGE, encoding: 'utf8', stdio: ['ignore', 'pipe', 'inherit'] });
  // The prepack script's own lines come first.
  [packed] = JSON.parse(said.slice(said.search(/^\[/m)));
  app = join(work, 'app');
  mkdirSync(app);
  writeFileSync(join(app, 'package.json'), JSON.stringify({ name: 'consumer', private: true, type: 'module' }));
  execFileSync('npm', ['install', '--offline', '--no-audit', '--no-fund', join(work, packed.filename)], { cwd: app, stdio: ['ignore', 'inherit', 'inherit'] });
  server = await startServer({ embeddedViewer: true });
  textures = (await (await fetch(`${server.url}/api/v1/textures`)).json()).textures;
});

after(async () => {
  await server?.stop();
  if (work) rmSync(work, { recursive: true, force: true });
});

/** The ```js blocks of the README's section `## heading`. */
function readmeBlocks(heading) {
  const at = README.indexOf(`\n## ${heading}\n`);
  assert.ok(at >= 0, `no section "${heading}" in the package's README`);
  const section = README.slice(at + 1).split(/\n## /)[0];
  const blocks = [...section.matchAll(/```js\n([\s\S]*?)```/g)].map((m) => m[1]);
  assert.ok(blocks.length > 0, `no js block in "${heading}"`);
  return blocks;
}

/** The README's example, rendering `info`'s texture on our server. */
function example(info) {
  const [code] = readmeBlocks('Render a tile in ten lines');
  assert.equal(code.split(PLACEHOLDER).length, 2, `the example names its texture once, as ${PLACEHOLDER}`);
  return code.replace(PLACEHOLDER, `${server.url}/api/v1/textures/${info.id}`);
}

/** Runs `code` as an ES module of the consumer project (so it imports the package by name); answers its stdout. */
function runInApp(name, code, args = []) {
  writeFileSync(join(app, name), code);
  return execFileSync(process.execPath, [join(app, name), ...args], { cwd: app, encoding: 'utf8', stdio: ['ignore', 'pipe', 'inherit'] });
}

/** A texture of every model, the animated one where a model has one (so frames are compared too). */
function texturePerModel() {
  return MODELS.map((model) => {
    const own = textures.filter((t) => t.model === model);
    assert.ok(own.length > 0, `the server has no texture of model ${model}`);
    return own.find((t) => t.animated) || own[0];
  });
}

/** Tiles compared besides the example's 0/0/0: level 0's last (an edge tile), the coarsest level's, a later frame. */
function moreTiles(info) {
  const last = (size) => Math.ceil(size / info.tile_size) - 1;
  const tiles = [
    [0, last(info.width), last(info.height), 0],
    [info.levels - 1, 0, 0, 0],
  ];
  if (info.animated) tiles.push([0, 0, 0, 7]);
  return tiles;
}

test('the tarball holds the package and nothing else: the viewer’s wrapper unchanged and a module per model', () => {
  const expected = ['README.md', 'index.d.ts', 'index.js', 'node.js', 'package.json', 'vtex-synth.js', ...MODELS.map((m) => `wasm/${moduleFile(m)}`)];
  assert.deepEqual(packed.files.map((f) => f.path).sort(), expected.sort());
  console.log(`${packed.filename}: ${packed.entryCount} files, ${packed.size} B packed, ${packed.unpackedSize} B unpacked`);
  const installed = join(app, 'node_modules', 'vtex-synth');
  assert.deepEqual(readFileSync(join(installed, 'vtex-synth.js')), readFileSync(join(ROOT, 'client-web', 'src', 'shared', 'vtex-synth.js')));
  for (const model of MODELS) assert.deepEqual(readFileSync(join(installed, 'wasm', moduleFile(model))), readFileSync(modulePath(model)), model);
  const pkg = JSON.parse(readFileSync(join(installed, 'package.json'), 'utf8'));
  assert.equal(pkg.license, readFileSync(join(ROOT, 'Cargo.toml'), 'utf8').match(/^license = "(.*)"$/m)[1], "the workspace's licence");
});

test('resolved by its name: Node takes node.js, browsers index.js, each module is a subpath; both export what index.d.ts declares', () => {
  const resolved = JSON.parse(
    runInApp(
      'resolve.mjs',
      `const tryResolve = (s) => { try { return import.meta.resolve(s); } catch (e) { return e.code; } };
console.log(JSON.stringify({
  node: tryResolve('vtex-synth'),
  modules: ${JSON.stringify(MODELS)}.map((m) => tryResolve('vtex-synth/wasm/vtex_synth_' + m + '.wasm')),
  wrapper: tryResolve('vtex-synth/vtex-synth.js'),
  node_exports: Object.keys(await import('vtex-synth')).sort(),
  browser_exports: Object.keys(await import('./node_modules/vtex-synth/index.js')).sort(),
}));`,
    ),
  );
  const at = (path) => new URL(`node_modules/vtex-synth/${path}`, pathToFileURL(`${app}/`)).href;
  assert.equal(resolved.node, at('node.js'));
  assert.deepEqual(resolved.modules, MODELS.map((m) => at(`wasm/${moduleFile(m)}`)));
  assert.equal(resolved.wrapper, 'ERR_PACKAGE_PATH_NOT_EXPORTED', 'files outside the exports map are not importable');
  const declared = [...readFileSync(join(PACKAGE, 'index.d.ts'), 'utf8').matchAll(/^export (?:class|function) (\w+)/gm)].map((m) => m[1]).sort();
  assert.deepEqual(resolved.node_exports, declared);
  assert.deepEqual(resolved.browser_exports, declared);
});

test("the README's examples, as written there, render every model's tiles and a region in Node like the server", async () => {
  const [code] = readmeBlocks('Render a tile in ten lines');
  const lines = code.split('\n').filter((l) => l.trim() !== '');
  assert.ok(lines.length <= 10, `the example takes ${lines.length} lines`);
  // The README's region: its render call, and the server's region endpoint for the same.
  const regionCode = readmeBlocks('In a page: an ImageData, a canvas').find((b) => b.includes('texture.render('));
  const region = new Function(`return ${regionCode.match(/texture\.render\((\{[^}]*\})\)/)[1]}`)();
  const regionQuery = `level=${region.level}&x=${region.x}&y=${region.y}&w=${region.width}&h=${region.height}&frame=${region.frame}&format=rgba`;
  const chosen = texturePerModel();
  assert.ok(chosen.some((t) => t.animated), 'no animated texture among those compared');
  for (const info of chosen) {
    const out = join(work, `out-${info.model}`);
    mkdirSync(out);
    // After the examples: what they made, written out for the comparison.
    runInApp(
      `example-${info.model}.mjs`,
      `${example(info)}
const { writeFileSync } = await import('node:fs');
const rendered = { info: texture.info, tiles: [[0, 0, 0, 0, tile]] };
for (const [level, tx, ty, frame] of ${JSON.stringify(moreTiles(info))}) rendered.tiles.push([level, tx, ty, frame, texture.renderTile(level, tx, ty, frame)]);
rendered.tiles.forEach(([, , , , t], i) => writeFileSync(\`\${process.argv[2]}/\${i}.rgba\`, t.data));
writeFileSync(\`\${process.argv[2]}/rendered.json\`, JSON.stringify({ info: rendered.info, tiles: rendered.tiles.map(([l, x, y, f, t]) => [l, x, y, f, t.width, t.height]) }));
${regionCode}
writeFileSync(\`\${process.argv[2]}/region.rgba\`, rgba);
`,
      [out],
    );
    const rendered = JSON.parse(readFileSync(join(out, 'rendered.json'), 'utf8'));
    assert.deepEqual(rendered.info, info, `${info.name}: the module's info is the server's`);
    for (const [i, [level, tx, ty, frame, width, height]] of rendered.tiles.entries()) {
      const what = `${info.name} (${info.model}): tile ${level}/${tx}/${ty} at frame ${frame}`;
      const theirs = await fetchServerTile(server.url, info, level, tx, ty, frame);
      assert.deepEqual([width, height], [theirs.width, theirs.height], what);
      assert.ok(readFileSync(join(out, `${i}.rgba`)).equals(theirs.data), `${what}: other bytes than the server's`);
    }
    const theirs = await fetch(`${server.url}/api/v1/textures/${info.id}/region?${regionQuery}`);
    assert.equal(theirs.status, 200, `${info.name}: region ${regionQuery}`);
    assert.ok(readFileSync(join(out, 'region.rgba')).equals(Buffer.from(await theirs.arrayBuffer())), `${info.name}: region ${regionQuery}: other bytes than the server's`);
    console.log(`${info.model}: ${info.name} (${info.width} × ${info.height}), ${rendered.tiles.length} tiles and a region equal to the server's`);
  }
});

test("in Chromium, through the README's import map, the example draws the server's tile on a canvas with the package's module", async () => {
  const importMap = README.match(/<script type="importmap">.*?<\/script>/);
  assert.ok(importMap, 'no import map in the README');
  const info = texturePerModel().find((t) => t.model === 'chaos-mosaic');
  // The example, then the README's canvas snippet on a canvas of the tile's size.
  writeFileSync(
    join(app, 'page.mjs'),
    `${example(info)}
const canvas = document.body.appendChild(document.createElement('canvas'));
[canvas.width, canvas.height] = [tile.width, tile.height];
${readmeBlocks('In a page: an ImageData, a canvas')[0]}
const missing = await loadModule('no-such-model').then(() => 'loaded', (e) => \`\${e.name}: \${e.message}\`);
window.drawn = { width: tile.width, height: tile.height, pixels: Array.from(canvas.getContext('2d').getImageData(0, 0, tile.width, tile.height).data), missing };
`,
  );
  writeFileSync(join(app, 'page.html'), `<!doctype html>\n<meta charset="utf-8">\n${importMap[0]}\n<script type="module" src="page.mjs"></script>\n`);
  const site = await staticServer(app);
  const browser = await launchBrowser({ width: 400, height: 400 });
  try {
    const page = await browser.context.newPage();
    const errors = [];
    const requests = [];
    page.on('pageerror', (e) => errors.push(String(e)));
    page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
    page.on('request', (r) => requests.push(r.url()));
    await page.goto(`${site.url}/page.html`);
    await page.waitForFunction(() => window.drawn, null, { timeout: 60_000 });
    const drawn = await page.evaluate(() => window.drawn);
    const theirs = await fetchServerTile(server.url, info, 0, 0, 0);
    assert.deepEqual([drawn.width, drawn.height], [theirs.width, theirs.height]);
    assert.ok(Buffer.from(drawn.pixels).equals(theirs.data), "the canvas shows other pixels than the server's tile");
    const moduleUrl = `${site.url}/node_modules/vtex-synth/wasm/${moduleFile(info.model)}`;
    assert.ok(requests.includes(moduleUrl), `the module is fetched from the package: ${requests.join(', ')}`);
    assert.equal(drawn.missing, `SynthError: no module for model \`no-such-model\`: ${site.url}/node_modules/vtex-synth/wasm/vtex_synth_no-such-model.wasm answered HTTP 404`);
    // The failed fetch of the missing module is the one error the console may show.
    assert.deepEqual(errors.filter((e) => !/404/.test(e)), []);
  } finally {
    await browser.close();
    await site.stop();
  }
});

test('refusals through the package are SynthErrors that name the problem', () => {
  const said = JSON.parse(
    runInApp(
      'refusals.mjs',
      `import { instantiate, loadModule } from 'vtex-synth';
const refusal = (f) => f().then(() => 'accepted', (e) => \`\${e.name}: \${e.message}\`);
const synth = await instantiate(await loadModule('lcm'));
console.log(JSON.stringify([
  await refusal(() => loadModule('no-such-model')),
  await refusal(() => loadModule('../../../etc/passwd')),
  await refusal(async () => synth.open(new TextEncoder().encode('<!doctype html>'), 256)),
]));`,
    ),
  );
  const missing = new URL(`node_modules/vtex-synth/wasm/vtex_synth_no-such-model.wasm`, pathToFileURL(`${app}/`)).href;
  assert.deepEqual(said, [
    `SynthError: no module for model \`no-such-model\`: ${missing} does not exist`,
    'SynthError: not a model name: "../../../etc/passwd"',
    'SynthError: invalid bundle: not a vtex bundle (bad magic)',
  ]);
});

test('tsc --strict accepts a typed consumer of the package and refuses a mistyped one on exactly its wrong lines', () => {
  cpSync(join(ROOT, 'tests', 'npm', 'types'), join(app, 'types'), { recursive: true });
  const tsc = (file) =>
    spawnSync(
      TSC,
      ['--noEmit', '--pretty', 'false', '--strict', '--skipLibCheck', 'false', '--target', 'es2022', '--lib', 'es2022,dom', '--module', 'nodenext', '--moduleResolution', 'nodenext', file],
      { cwd: app, encoding: 'utf8' },
    );
  const typed = tsc('types/consumer.ts');
  assert.equal(typed.status, 0, `tsc refused the typed consumer:\n${typed.stdout}${typed.stderr}`);
  const mistyped = tsc('types/mistyped.ts');
  assert.notEqual(mistyped.status, 0, 'tsc accepted the mistyped consumer');
  const refused = [...new Set([...mistyped.stdout.matchAll(/mistyped\.ts\((\d+),\d+\): error TS\d+/g)].map((m) => +m[1]))];
  const wrong = readFileSync(join(app, 'types', 'mistyped.ts'), 'utf8')
    .split('\n')
    .flatMap((line, i) => (/\/\/ wrong:/.test(line) ? [i + 1] : []));
  assert.ok(wrong.length >= 8);
  assert.deepEqual(refused, wrong, `tsc's errors:\n${mistyped.stdout}`);
});
