// The browser sessions the bandwidth experiment (bench/bandwidth.mjs) and the world bench
// (bench/world/run.mjs) measure: a scripted pan-and-zoom session in the viewer, and a walk along
// the 3D world's scripted path, each in headless Chromium against a fresh `vtex serve`, under
// Chromium's network emulation, with an empty HTTP cache (a first visit) or with the page's code
// and the synthesis modules already in it (a returning visitor).
//
// Bytes on the wire are DevTools' encodedDataLength of every request the page makes, plus the
// Resource Timing transferSize of the viewer's tile batches, which its tile Worker fetches (the
// page's DevTools session does not see a Worker's requests). CPU is that of every Chromium
// process (client) and of `vtex serve` (server).
import { readdirSync, readFileSync } from 'node:fs';
import { launchBrowser, startServer, waitForIdle } from '../../tests/browser/lib.mjs';

/** Network profiles: Chromium's emulation (Network.emulateNetworkConditions), null = loopback. */
export const PROFILES = {
  loopback: { label: 'loopback', conditions: null },
  '10mbit': { label: '10 Mbit/s, 40 ms RTT', conditions: { latency: 40, downloadThroughput: 10e6 / 8, uploadThroughput: 10e6 / 8 } },
  // DevTools' "Slow 4G" preset (Lighthouse's mobile throttling: 1.6 Mbit/s, 750 kbit/s, 150 ms
  // RTT, scaled as DevTools scales it for request-level emulation).
  slow4g: { label: 'Slow 4G (1.44 Mbit/s, 562.5 ms)', conditions: { latency: 562.5, downloadThroughput: (1.6e6 * 0.9) / 8, uploadThroughput: (750e3 * 0.9) / 8 } },
};

/** What a request carried, by its URL: the texture's pixels (tiles, pages), its encoding, a synthesis module, or code. */
export function category(url) {
  const path = new URL(url).pathname;
  if (path.endsWith('.wasm')) return 'module';
  if (/\/encoding$/.test(path)) return 'encoding';
  if (/^\/api\/v1\/textures\/[^/]+\/(tiles|pages|page-metatiles)\//.test(path)) return 'pixels';
  return 'code';
}

const sum = (xs) => xs.reduce((a, b) => a + b, 0);
const TICK = 100; // USER_HZ: /proc/<pid>/stat counts CPU in 1/100 s on Linux

/** CPU seconds (user + system) of `pid`, or 0 when it is gone. */
export function cpuOf(pid) {
  try {
    const stat = readFileSync(`/proc/${pid}/stat`, 'utf8');
    const fields = stat.slice(stat.lastIndexOf(')') + 2).split(' ');
    return (Number(fields[11]) + Number(fields[12])) / TICK;
  } catch {
    return 0;
  }
}

/** CPU seconds of every process of the Chromium using `profile` (it and its descendants). */
function chromiumCpu(profile) {
  const procs = [];
  for (const name of readdirSync('/proc')) {
    if (!/^\d+$/.test(name)) continue;
    try {
      const stat = readFileSync(`/proc/${name}/stat`, 'utf8');
      const ppid = Number(stat.slice(stat.lastIndexOf(')') + 2).split(' ')[1]);
      const cmd = readFileSync(`/proc/${name}/cmdline`, 'utf8');
      procs.push({ pid: Number(name), ppid, mine: cmd.includes(profile) });
    } catch {
      // the process ended while we looked
    }
  }
  const ours = new Set(procs.filter((p) => p.mine).map((p) => p.pid));
  for (let grew = true; grew; ) {
    grew = false;
    for (const p of procs) if (!ours.has(p.pid) && ours.has(p.ppid)) grew = ours.add(p.pid);
  }
  return sum([...ours].map(cpuOf));
}

/**
 * Runs `body(page, server)` in a fresh server and browser under `profile`, counting the page's
 * requests from the start of `body`. With `returning`, the HTTP cache first gets the code and
 * module URLs a first visit fetched (`returning.urls`), as a visitor who has been on the site
 * before has them; they are then revalidated (304), not downloaded. Resolves to body's result
 * with bytes and requests by category, the URLs fetched by category, and CPU seconds.
 */
async function measured({ dataDir, profile, size, returning = null }, body) {
  const server = await startServer({ dataDir, embeddedViewer: true });
  const browser = await launchBrowser(size);
  try {
    const page = await browser.context.newPage();
    if (returning) {
      await page.goto(`${server.url}/api/v1/models`);
      await page.evaluate((urls) => Promise.all(urls.map((u) => fetch(u).then((r) => r.arrayBuffer()))), [...returning.urls.code, ...returning.urls.module]);
    }
    const cdp = await browser.context.newCDPSession(page);
    await cdp.send('Network.enable');
    const conditions = PROFILES[profile].conditions;
    if (conditions) await cdp.send('Network.emulateNetworkConditions', { offline: false, ...conditions });
    const seen = new Map();
    const bytes = { code: 0, module: 0, encoding: 0, pixels: 0 };
    const requests = { code: 0, module: 0, encoding: 0, pixels: 0 };
    const urls = { code: new Set(), module: new Set() };
    cdp.on('Network.requestWillBeSent', (e) => seen.set(e.requestId, e.request.url));
    cdp.on('Network.loadingFinished', (e) => {
      const url = seen.get(e.requestId);
      if (!url || !/^http/.test(url)) return;
      const kind = category(url);
      bytes[kind] += e.encodedDataLength;
      requests[kind]++;
      urls[kind]?.add(url.replace(server.url, '{server}'));
    });
    const cpu0 = { client: chromiumCpu(browser.profile), server: cpuOf(server.pid) };
    const result = await body(page, server);
    const cpu = { client: chromiumCpu(browser.profile) - cpu0.client, server: cpuOf(server.pid) - cpu0.server };
    if (result.workerPixels) {
      bytes.pixels += result.workerPixels.bytes;
      requests.pixels += result.workerPixels.requests;
    }
    delete result.workerPixels;
    if (returning && bytes.module > 2000) throw new Error(`a returning visitor downloaded the module again (${bytes.module} B): the priming did not reach the HTTP cache`);
    const list = (set) => [...set].map((u) => u.replace('{server}', ''));
    return { ...result, profile, returning: Boolean(returning), bytes, requests, total: sum(Object.values(bytes)), urls: { code: list(urls.code), module: list(urls.module) }, cpu };
  } finally {
    await browser.close();
    await server.stop();
  }
}

/**
 * The viewer on texture `info` in `mode` (a tile format, or `client` for client synthesis),
 * through `views` ([zoom, x, y] with x, y as fractions of the texture), each applied at once
 * after the previous one is complete; cut after `capMs`. The first view is the whole texture.
 * `returning`: a first visit's result, whose code and module the HTTP cache holds.
 */
export async function viewerSession({ dataDir, info, mode, profile, size, views, capMs, returning }) {
  return measured({ dataDir, profile, size, returning }, async (page, server) => {
    const result = { model: info.model, mode, views: 0, complete: false };
    const query = mode === 'client' ? 'synth=client' : `format=${mode}`;
    const t0 = performance.now();
    const left = () => Math.max(1, capMs - (performance.now() - t0));
    try {
      await page.goto(`${server.url}/?texture=${info.id}&${query}&debug`, { timeout: left() });
      await page.waitForFunction(() => window.vtexViewer && window.vtexViewer.state.item, null, { timeout: left() });
      await waitForIdle(page, left());
      result.firstViewMs = performance.now() - t0;
      for (const [zoom, fx, fy] of views.slice(1)) {
        await page.evaluate(([zoom, x, y]) => window.vtexViewer.setView({ zoom, x, y }, true), [zoom, fx * info.width, fy * info.height]);
        await waitForIdle(page, left());
        result.views++;
      }
      result.complete = true;
    } catch (e) {
      if (e.name !== 'TimeoutError') throw e;
    }
    result.endMs = performance.now() - t0;
    const stats = await page.evaluate(() => window.vtexViewer?.stats.snapshot() ?? null);
    result.tiles = stats ? stats.loaded : 0;
    result.failed = stats ? stats.failed : 0;
    if (mode !== 'client' && stats) result.workerPixels = { bytes: stats.wireBytes, requests: stats.batches };
    return result;
  });
}

/**
 * The 3D world (world.html) with pages from `mode` (`client`: synthesized in the browser; `jpg`,
 * `ktx2`: fetched from the server), walked once along its scripted path of `steps` frames, which
 * starts once the first frame is complete; cut after `capMs`. `stats` is the world's own
 * (window.vtexWorld.stats(): frame times, the resident share of the pages each step needed).
 * `screenshot`: a path to save the walk's last frame at.
 */
export async function worldWalk({ dataDir, mode, profile, size, steps, capMs, returning, screenshot = null }) {
  return measured({ dataDir, profile, size, returning }, async (page, server) => {
    const t0 = performance.now();
    await page.goto(`${server.url}/world.html?pages=${mode}&path=bench&frames=${steps}&debug`);
    let complete = true;
    try {
      await page.waitForFunction(() => window.vtexWorld && (window.vtexWorld.error || window.vtexWorld.state.done), null, { timeout: capMs, polling: 250 });
    } catch (e) {
      if (e.name !== 'TimeoutError') throw e;
      complete = false;
    }
    const endMs = performance.now() - t0;
    const stats = await page.evaluate(() => window.vtexWorld.error || window.vtexWorld.stats());
    if (typeof stats === 'string' || stats.error) throw new Error(`world, ${mode} pages: ${stats.error || stats}`);
    if (screenshot) await page.screenshot({ path: screenshot });
    return { model: 'world', mode, complete, firstViewMs: stats.firstComplete ?? undefined, endMs, stats };
  });
}
