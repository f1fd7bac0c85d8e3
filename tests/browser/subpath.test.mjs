// vtex mounted under a sub-path behind Debian's nginx, configured with the blocks of
// docs/deployment.md: the viewer (built into the binary, and from --web-dir), client mode, the
// VT demo and an `export-web` folder draw through the prefix with no request escaping it, and every absolute URL vtex
// writes (IIIF, TileJSON, OpenAPI, model examples) points under the prefix and answers through
// nginx — from --public-url, and, without it, from the X-Forwarded-* or Forwarded headers of a
// trusted nginx (and never from those of an untrusted peer).
// Run: node --test tests/browser/   (needs nginx, target/release/vtex and client-web/dist built)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync, spawn } from 'node:child_process';
import { chmodSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import http from 'node:http';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { NGINX, freePort } from '../replicas/topology.mjs';
import {
  ROOT,
  VTEX_BIN,
  WEB_DIR,
  compareScreenToServerTile,
  debugUrl,
  exited,
  launchBrowser,
  openViewer,
  setAlignedView,
  startServer,
  waitForIdle,
} from './lib.mjs';

const FLAGSHIP = 'Pebbles — chaos mosaic 100k';
// The upstream address in the documented blocks, replaced by each test server's.
const DOC_UPSTREAM = 'http://127.0.0.1:8080/';

let nginx;
let dir;
let port;
// `pub`: --public-url, the viewer built into the binary, behind /vtex/. `fwd`: no public URL,
// trusting 127.0.0.1, the viewer from --web-dir, behind /fwd/ (X-Forwarded-*) and /rfc/ (Forwarded).
let pub;
let fwd;
let browser;
let big;

/** The nginx blocks of docs/deployment.md marked as run by this test, in order. */
function documentedBlocks() {
  const md = readFileSync(join(ROOT, 'docs', 'deployment.md'), 'utf8');
  const marked = /<!-- tests\/browser\/subpath\.test\.mjs runs this block[^>]*-->\n```nginx\n([\s\S]*?)```/g;
  const blocks = [...md.matchAll(marked)].map((m) => m[1]);
  assert.equal(blocks.length, 2, 'docs/deployment.md has the sub-path block and the forwarded-headers block');
  for (const b of blocks) assert.ok(b.includes(`proxy_pass ${DOC_UPSTREAM};`), `the block proxies to ${DOC_UPSTREAM}: ${b}`);
  return blocks;
}

/** A whole nginx configuration around `locations`, its files under `dir`, logging every request's status and URI. */
function nginxConf(locations) {
  const temp = ['client_body', 'proxy', 'fastcgi', 'uwsgi', 'scgi'].map((t) => `${t}_temp_path ${join(dir, t)};`).join('\n  ');
  return `worker_processes 1;
pid ${join(dir, 'nginx.pid')};
error_log stderr warn;
events { worker_connections 256; }
http {
  include /etc/nginx/mime.types;
  log_format paths '$status $request_uri';
  access_log ${join(dir, 'access.log')} paths;
  ${temp}
  server {
    listen 127.0.0.1:${port};
${locations}
    # Anything outside the prefixes escaped them.
    location / { return 404; }
  }
}
`;
}

before(async () => {
  dir = mkdtempSync(join(tmpdir(), 'vtex-subpath-'));
  chmodSync(dir, 0o755); // nginx's workers run as an unprivileged user when started as root
  port = await freePort();
  // The environment variables, not the flags: a vtex that does not know them still starts.
  pub = await startServer({ embeddedViewer: true, env: { VTEX_PUBLIC_URL: `http://127.0.0.1:${port}/vtex/`, VTEX_TRUSTED_PROXIES: '127.0.0.1' } });
  fwd = await startServer({ dataDir: pub.dataDir, extraArgs: ['--no-demos'], env: { VTEX_TRUSTED_PROXIES: '127.0.0.1' } });
  const { textures } = await (await fetch(`${pub.url}/api/v1/textures`)).json();
  big = textures.find((t) => t.name === FLAGSHIP);
  assert.ok(big, `the demo textures include ${FLAGSHIP}`);
  execFileSync(VTEX_BIN, ['export-web', big.id, join(dir, 'export'), '--data-dir', pub.dataDir, '--web-dir', WEB_DIR], { env: { ...process.env, VTEX_LOG: 'warn' } });
  const [subPath, forwarded] = documentedBlocks();
  const rfc7239 = `location /rfc/ {
    proxy_pass ${DOC_UPSTREAM};
    proxy_set_header Forwarded "for=$remote_addr;host=\\"$http_host\\";proto=$scheme";
    proxy_set_header X-Forwarded-Prefix /rfc;
}`;
  const locations = [
    subPath.replace(DOC_UPSTREAM, `${pub.url}/`),
    forwarded.replaceAll('/vtex', '/fwd').replace(DOC_UPSTREAM, `${fwd.url}/`),
    rfc7239.replace(DOC_UPSTREAM, `${fwd.url}/`),
    `location /exp/ { alias ${join(dir, 'export')}/; }`,
  ].join('\n');
  writeFileSync(join(dir, 'nginx.conf'), nginxConf(locations));
  nginx = spawn(NGINX, ['-p', dir, '-c', join(dir, 'nginx.conf'), '-e', 'stderr', '-g', 'daemon off;'], { stdio: ['ignore', 'ignore', 'pipe'] });
  let nginxErr = '';
  nginx.stderr.on('data', (d) => (nginxErr += d));
  for (let t = 0; ; t++) {
    if (nginx.exitCode !== null || t > 200) throw new Error(`nginx did not start:\n${nginxErr}`);
    try {
      if ((await fetch(`http://127.0.0.1:${port}/vtex/healthz`)).ok) break;
    } catch {
      // not listening yet
    }
    await new Promise((r) => setTimeout(r, 25));
  }
  browser = await launchBrowser({ width: 800, height: 520 });
});

after(async () => {
  await browser?.close();
  if (nginx && nginx.exitCode === null) {
    nginx.kill('SIGQUIT');
    await exited(nginx);
  }
  await fwd?.stop();
  await pub?.stop();
  if (dir) rmSync(dir, { recursive: true, force: true });
});

const mounted = (prefix) => `http://127.0.0.1:${port}${prefix}`;

/** Lines of nginx's access log (`status uri`) written while `work` runs. */
async function nginxSaw(work) {
  const log = () => readFileSync(join(dir, 'access.log'), 'utf8');
  const before = log().length;
  await work();
  // nginx writes a request's line once it is answered; the page may still be finishing one.
  await new Promise((r) => setTimeout(r, 200));
  return log().slice(before).split('\n').filter(Boolean);
}

/** Every request the page made, and every request nginx received meanwhile, stayed under `base`. */
function assertUnder(base, pageRequests, nginxLines) {
  const path = new URL(base).pathname;
  const outside = pageRequests.filter((u) => !u.startsWith(`${base}/`) && !u.startsWith('data:'));
  assert.deepEqual(outside, [], `requests outside ${base}/`);
  const escaped = nginxLines.filter((l) => !l.split(' ')[1].startsWith(`${path}/`));
  assert.deepEqual(escaped, [], `requests nginx received outside ${path}/`);
  assert.ok(nginxLines.length > 0, 'the page went through nginx');
}

/** Opens the viewer at `url` and checks level-0 pixels at 1:1 against the server's tiles, through `base`. */
async function viewerDraws(base, url) {
  const { page, log } = await openViewer(browser.context, url);
  await waitForIdle(page, 120_000);
  await setAlignedView(page, 1, 73_000, 41_000);
  assert.equal(await compareScreenToServerTile(page, base, big, 0, 73_000, 41_000), 0, 'level-0 pixels exact');
  assert.deepEqual(log.badResponses, [], 'error responses');
  assert.deepEqual(log.errors, [], 'page errors');
  return { page, log };
}

test('the viewer built into the binary draws tiles under /vtex/ (--public-url), its links under the prefix', async () => {
  const base = mounted('/vtex');
  let requests;
  const lines = await nginxSaw(async () => {
    const { page, log } = await viewerDraws(base, `${base}/?texture=${big.id}`);
    assert.ok(log.requests.some((u) => u.startsWith(`${base}/api/v1/textures/${big.id}/metatiles/`)), 'tiles fetched through the prefix');
    assert.ok(log.requests.some((u) => new URL(u).pathname.startsWith('/vtex/assets/')), 'fingerprinted scripts through the prefix');
    assert.equal(await page.$eval('#vt-demo', (a) => a.href), `${base}/vt.html`);
    requests = log.requests;
    await page.close();
  });
  assertUnder(base, requests, lines);
});

test('client mode under /vtex/: the module, the encoding and the Workers through the prefix, tiles drawn', async () => {
  const base = mounted('/vtex');
  let requests;
  const lines = await nginxSaw(async () => {
    const { page, log } = await viewerDraws(base, `${base}/?texture=${big.id}&synth=client`);
    assert.ok(log.requests.includes(`${base}/vtex_synth_${big.model}.wasm`), "the synthesis module of the texture's model");
    assert.ok(log.requests.includes(`${base}/api/v1/textures/${big.id}/encoding`), 'the encoding');
    assert.deepEqual(log.requests.filter((u) => /\/api\/v1\/textures\/[^/]+\/(meta)?tiles/.test(u)), [], 'no tile from the server');
    requests = log.requests;
    await page.close();
  });
  assertUnder(base, requests, lines);
});

/** Opens `url` (with `?debug`) in a small page, logging every request and every error response. */
async function openLogged(url) {
  const page = await browser.context.newPage();
  await page.setViewportSize({ width: 480, height: 300 });
  const [requests, bad] = [[], []];
  page.on('request', (r) => requests.push(r.url()));
  page.on('response', (r) => r.status() >= 400 && bad.push(`${r.status()} ${r.url()}`));
  await page.goto(debugUrl(url));
  return { page, requests, bad };
}

test('the VT demo under /vtex/ streams its pages through the prefix', async () => {
  const base = mounted('/vtex');
  let requests;
  const lines = await nginxSaw(async () => {
    // A fixed camera: the demo settles once every page the view needs is resident.
    const { page, bad, requests: seen } = await openLogged(`${base}/vt.html?texture=${big.id}&format=rgba&camera=50000,50000,220,17,35`);
    requests = seen;
    await page.waitForFunction(() => window.vtDemo && (window.vtDemo.error || window.vtDemo.state.settled || window.vtDemo.state.done), null, {
      timeout: 120_000,
      polling: 100,
    });
    assert.equal(await page.evaluate(() => window.vtDemo.error || window.vtDemo.state.error), null, 'the demo reports no error');
    for (const route of ['pages', 'page-metatiles']) {
      const under = `${base}/api/v1/textures/${big.id}/${route}/`;
      assert.ok(requests.some((u) => u.startsWith(under)), `${route} requested through the prefix`);
    }
    assert.deepEqual(bad, [], 'error responses');
    assert.equal(await page.$eval('#back', (a) => a.href), `${base}/`);
    await page.close();
  });
  assertUnder(base, requests, lines);
});

test('the 3D world under /fwd/ synthesizes its pages from encodings fetched through the prefix', async () => {
  const base = mounted('/fwd');
  let requests;
  const lines = await nginxSaw(async () => {
    const { page, bad, requests: seen } = await openLogged(`${base}/world.html?camera=50000,51000,160,0,8`);
    requests = seen;
    await page.waitForFunction(() => window.vtexWorld && (window.vtexWorld.error || window.vtexWorld.state.settled), null, { timeout: 300_000, polling: 100 });
    assert.equal(await page.evaluate(() => window.vtexWorld.error || window.vtexWorld.state.error), null, 'the world reports no error');
    const textures = await page.evaluate(() => window.vtexWorld.state.textures.map((t) => ({ id: t.id, model: t.model })));
    for (const { id, model } of textures) {
      assert.ok(requests.includes(`${base}/api/v1/textures/${id}/encoding`), `encoding ${id} through the prefix`);
      assert.ok(requests.includes(`${base}/vtex_synth_${model}.wasm`), `the ${model} module through the prefix`);
    }
    assert.deepEqual(requests.filter((u) => /\/api\/v1\/textures\/[^/]+\/(pages|page-metatiles|tiles|metatiles)\//.test(u)), [], 'no page from the server');
    assert.deepEqual(bad, [], 'error responses');
    await page.close();
  });
  assertUnder(base, requests, lines);
});

/** GET `url` through nginx: its status, headers and body. */
async function get(url, init = {}) {
  const r = await fetch(url, { redirect: 'manual', ...init });
  return { status: r.status, headers: r.headers, body: Buffer.from(await r.arrayBuffer()) };
}

/**
 * The absolute URLs vtex writes, read through `base` (a prefix of nginx): each under `base`, and
 * each answering 200 through nginx.
 */
async function checkAbsoluteUrls(base) {
  const id = big.id;
  const service = `${base}/iiif/3/${id}`;
  const info = JSON.parse((await get(`${service}/info.json`)).body);
  assert.equal(info.id, service, 'IIIF id');
  const redirect = await get(service);
  assert.equal(redirect.status, 303);
  assert.equal(redirect.headers.get('location'), `${service}/info.json`, 'IIIF base URI redirect');
  const image = await get(`${info.id}/0,0,256,256/128,/0/default.png`);
  assert.equal(image.status, 200, 'an IIIF image through nginx');
  assert.ok(image.headers.get('link').includes(`<${service}/0,0,256,256/`), `canonical link: ${image.headers.get('link')}`);

  const tilejson = JSON.parse((await get(`${base}/api/v1/textures/${id}/tilejson.json`)).body);
  assert.ok(tilejson.tiles[0].startsWith(`${base}/api/v1/textures/${id}/xyz/`), `TileJSON tiles: ${tilejson.tiles[0]}`);
  const xyz = await get(tilejson.tiles[0].replace('{z}', '0').replace('{x}', '0').replace('{y}', '0'));
  assert.equal(xyz.status, 200, 'an XYZ tile through nginx');

  const dzi = await get(`${base}/dzi/${id}.dzi`);
  assert.equal(dzi.status, 200, 'the Deep Zoom descriptor');
  assert.equal((await get(`${base}/dzi/${id}_files/0/0_0.png`)).status, 200, 'a Deep Zoom tile beside it');

  const openapi = JSON.parse((await get(`${base}/api/v1/openapi.json`)).body);
  assert.deepEqual(openapi.servers, [{ url: base }], 'OpenAPI servers');
  assert.equal((await get(`${openapi.servers[0].url}/healthz`)).status, 200);

  const { models } = JSON.parse((await get(`${base}/api/v1/models`)).body);
  const hrefs = models.flatMap((m) => Object.values(m.example.inputs).map((i) => i.href));
  assert.ok(hrefs.length > 0);
  for (const href of hrefs) {
    assert.ok(href.startsWith(`${base}/api/v1/models/`), `model example ${href}`);
    assert.equal((await get(href)).status, 200, href);
  }
}

test('with --public-url, IIIF, TileJSON, Deep Zoom, OpenAPI and model URLs point under /vtex/ and answer through nginx', async () => {
  await checkAbsoluteUrls(mounted('/vtex'));
  // The public URL alone counts: forwarded headers, even from a trusted peer, change nothing.
  const spoofed = await get(`${pub.url}/iiif/3/${big.id}/info.json`, { headers: { 'x-forwarded-host': 'evil.example', 'x-forwarded-prefix': '/evil' } });
  assert.equal(JSON.parse(spoofed.body).id, `${mounted('/vtex')}/iiif/3/${big.id}`);
});

test('without --public-url, vtex trusting 127.0.0.1 takes its URL from nginx’s X-Forwarded-* headers, and from Forwarded', async () => {
  await checkAbsoluteUrls(mounted('/fwd'));
  await checkAbsoluteUrls(mounted('/rfc'));
});

test('the viewer from --web-dir draws tiles under /fwd/ (X-Forwarded-*), every request under the prefix', async () => {
  const base = mounted('/fwd');
  let requests;
  const lines = await nginxSaw(async () => {
    const { page, log } = await viewerDraws(base, `${base}/?texture=${big.id}`);
    requests = log.requests;
    await page.close();
  });
  assertUnder(base, requests, lines);
});

/** The IIIF id `server` writes for a request sent from the local address `from` with `headers`. */
function idFrom(server, from, headers) {
  const { hostname, port: p } = new URL(server.url);
  return new Promise((resolve, reject) => {
    const req = http.get({ host: hostname, port: p, path: `/iiif/3/${big.id}/info.json`, localAddress: from, headers }, (res) => {
      let body = '';
      res.on('data', (d) => (body += d));
      res.on('end', () => resolve(JSON.parse(body).id));
    });
    req.on('error', reject);
  });
}

test('forwarded headers are believed from the trusted 127.0.0.1 only: from 127.0.0.2 the Host alone counts', async () => {
  const spoof = { 'x-forwarded-host': 'evil.example', 'x-forwarded-proto': 'https', 'x-forwarded-prefix': '/evil', forwarded: 'host=evil.example;proto=https' };
  const own = `${fwd.url}/iiif/3/${big.id}`;
  assert.equal(await idFrom(fwd, '127.0.0.2', spoof), own, 'an untrusted peer cannot choose the URL');
  assert.equal(await idFrom(fwd, '127.0.0.1', spoof), `https://evil.example/evil/iiif/3/${big.id}`, 'a trusted peer can');
  assert.equal(await idFrom(fwd, '127.0.0.1', {}), own, 'no forwarded header: the Host');
});

test('an export-web folder hosted under /exp/ by nginx draws the texture, every request under the prefix', async () => {
  const base = mounted('/exp');
  let requests;
  const lines = await nginxSaw(async () => {
    const { page, log } = await openViewer(browser.context, `${base}/`);
    await waitForIdle(page, 120_000);
    await setAlignedView(page, 1, 73_000, 41_000);
    assert.equal(await compareScreenToServerTile(page, mounted('/vtex'), big, 0, 73_000, 41_000), 0, 'level-0 pixels exact');
    assert.deepEqual(log.badResponses, [], 'error responses');
    requests = log.requests;
    await page.close();
  });
  // The server's tiles the comparison fetched went to /vtex/; the page's requests alone count.
  assertUnder(base, requests, lines.filter((l) => !l.includes(' /vtex/')));
});
