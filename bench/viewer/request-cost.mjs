// What one tile request costs Chromium: CPU time of its processes (from /proc, Linux) around
// N concurrent fetches of tiles already in the server's cache, made from the idle viewer page.
//
//   node bench/viewer/request-cost.mjs [--tiles 128] [--rounds 2]
//
// Compares raw RGBA (256 KiB) with JPEG tiles (~10 KiB), `cache: 'no-store'` with the default
// (the response is also written to the HTTP disk cache), one request per tile with all N in
// one batched request (what the viewer sends, read with its FrameReader), and the bare
// DevTools driver of the bench with Playwright (which reports every request to its driver).
// curl fetching the same tiles over 6 connections is the server-side reference.
import { execFileSync } from 'node:child_process';
import { readFileSync, readdirSync } from 'node:fs';
import { parseArgs } from 'node:util';
import { debugUrl, launchBrowser, openViewer, startServer } from '../../tests/browser/lib.mjs';
import { launchBare } from './cdp.mjs';

const { values: args } = parseArgs({
  options: { tiles: { type: 'string', default: '128' }, rounds: { type: 'string', default: '2' } },
});
const N = Number(args.tiles);
const TICK_MS = 10; // /proc/<pid>/stat counts clock ticks (USER_HZ = 100 on Linux)

/** CPU ms used so far by Chromium's processes, by process type. */
function chromiumCpu() {
  const by = {};
  for (const pid of readdirSync('/proc').filter((p) => /^\d+$/.test(p))) {
    let cmd;
    let stat;
    try {
      cmd = readFileSync(`/proc/${pid}/cmdline`, 'utf8');
      stat = readFileSync(`/proc/${pid}/stat`, 'utf8');
    } catch {
      continue; // exited meanwhile
    }
    // Chromium rewrites its processes' titles, so argv may be one space-separated string.
    if (!/^\S*chromium/.test(cmd)) continue;
    const type = (cmd.match(/--type=([a-z-]+)/) || [, 'browser'])[1];
    const sub = (cmd.match(/--utility-sub-type=([\w.]+)/) || [])[1];
    const key = sub ? sub.replace(/\.mojom\./, ' ').split(' ')[0] : type;
    const f = stat.slice(stat.lastIndexOf(')') + 2).split(' ');
    by[key] = (by[key] || 0) + (Number(f[11]) + Number(f[12])) * TICK_MS;
  }
  return by;
}

/** In the page: fetches `urls` at once, reads each body as the viewer does; wall ms. */
function fetchAll({ urls, format, noStore }) {
  const t0 = performance.now();
  return Promise.all(
    urls.map(async (u) => {
      const r = await fetch(u, noStore ? { cache: 'no-store' } : {});
      if (!r.ok) throw new Error(`HTTP ${r.status} for ${u}`);
      if (format === 'rgba') {
        const w = Number(r.headers.get('X-Vtex-Width'));
        const h = Number(r.headers.get('X-Vtex-Height'));
        const c = document.createElement('canvas');
        c.width = w;
        c.height = h;
        c.getContext('2d').putImageData(new ImageData(new Uint8ClampedArray(await r.arrayBuffer()), w, h), 0, 0);
      } else {
        (await createImageBitmap(await r.blob())).close();
      }
    }),
  ).then(() => performance.now() - t0);
}

/** In the page: the same tiles as one batched request, read frame by frame as the viewer does. */
async function fetchBatch({ urls }) {
  const { FrameReader } = await import('/shared/batch.js');
  const t0 = performance.now();
  const m = urls[0].match(/^(.*)\/tiles\/\d+\/\d+\/\d+\.(\w+)$/);
  const list = urls.map((u) => u.match(/\/tiles\/(\d+\/\d+\/\d+)\./)[1]).join(',');
  const r = await fetch(`${m[1]}/tiles?format=${m[2]}&tiles=${list}`);
  if (!r.ok) throw new Error(`HTTP ${r.status} for the batch`);
  let n = 0;
  const reader = new FrameReader((f) => {
    const c = document.createElement('canvas');
    c.width = f.width;
    c.height = f.height;
    const px = new Uint8ClampedArray(f.body.buffer, f.body.byteOffset, f.body.length);
    c.getContext('2d').putImageData(new ImageData(px, f.width, f.height), 0, 0);
    n++;
  });
  const body = r.body.getReader();
  for (;;) {
    const { done, value } = await body.read();
    if (done) break;
    reader.push(value);
  }
  if (n !== urls.length) throw new Error(`the batch carried ${n} of ${urls.length} tiles`);
  return performance.now() - t0;
}

const server = await startServer({ extraArgs: ['--cache-mb', '2048'] });
try {
  const textures = (await (await fetch(`${server.url}/api/v1/textures`)).json()).textures;
  const big = textures.find((t) => t.model === 'chaos-mosaic' && t.width >= 100_000);
  let set = 0;
  // A fresh block of N level-2 tiles for every measurement (never in the browser's cache).
  const urls = (format) => {
    const x0 = 16 * (set % 6);
    const y0 = 12 * Math.floor(set++ / 6);
    return Array.from({ length: N }, (_, i) => `/api/v1/textures/${big.id}/tiles/2/${x0 + (i % 16)}/${y0 + Math.floor(i / 16)}.${format}`);
  };
  const cases = [];
  for (let round = 0; round < Number(args.rounds); round++) {
    for (const driver of ['cdp', 'playwright']) {
      for (const [format, noStore] of [['rgba', true], ['jpg', true], ['rgba', false]]) cases.push({ driver, format, noStore });
      cases.push({ driver, format: 'rgba', noStore: true, batch: true });
    }
  }
  // Warm the server's cache for every block first, so only the browser is measured.
  const plan = cases.map((c) => ({ ...c, urls: urls(c.format) }));
  for (const c of plan) await Promise.all(c.urls.map((u) => fetch(server.url + u).then((r) => r.arrayBuffer())));

  const pages = {};
  const url = `${server.url}/?texture=${big.id}&zoom=0.01&x=50000&y=50000`;
  pages.cdp = await launchBare(debugUrl(url));
  await pages.cdp.waitFor(() => window.vtexViewer && window.vtexViewer.state.item && window.vtexViewer.state.item.getFullyLoaded());
  const pw = await launchBrowser();
  const p = (await openViewer(pw.context, url)).page;
  pages.playwright = { evaluate: (fn, arg) => p.evaluate(fn, arg) };
  await new Promise((r) => setTimeout(r, 1000));

  console.log(`${N} concurrent tile fetches from the idle viewer page; Chromium CPU per tile (ms) by process`);
  console.log('| driver | tiles | requests | cache | wall ms | CPU ms/tile | renderer | network | browser | other |');
  console.log('|---|---|---|---|---|---|---|---|---|---|');
  for (const c of plan) {
    const before = chromiumCpu();
    const wall = c.batch
      ? await pages[c.driver].evaluate(fetchBatch, { urls: c.urls })
      : await pages[c.driver].evaluate(fetchAll, { urls: c.urls, format: c.format, noStore: c.noStore });
    const after = chromiumCpu();
    const d = {};
    for (const k of Object.keys(after)) d[k] = (after[k] - (before[k] || 0)) / N;
    const total = Object.values(d).reduce((a, b) => a + b, 0);
    const other = total - (d.renderer || 0) - (d.network || 0) - (d.browser || 0);
    const f = (v) => (v || 0).toFixed(2);
    console.log(`| ${c.driver} | ${c.format} | ${c.batch ? '1 batch' : `${N}`} | ${c.batch ? 'no-store (batch)' : c.noStore ? 'no-store' : 'HTTP cache'} | ${wall.toFixed(0)} | ${f(total)} | ${f(d.renderer)} | ${f(d.network)} | ${f(d.browser)} | ${f(other)} |`);
  }
  await pages.cdp.close();
  await pw.close();

  const ref = urls('rgba');
  await Promise.all(ref.map((u) => fetch(server.url + u).then((r) => r.arrayBuffer())));
  const t0 = performance.now();
  execFileSync('curl', ['-s', '--parallel', '--parallel-max', '6', ...ref.flatMap((u) => ['-o', '/dev/null', server.url + u])]);
  console.log(`\ncurl, same ${N} rgba tiles over 6 connections: ${(performance.now() - t0).toFixed(0)} ms wall`);
} finally {
  await server.stop();
}
