// The WebGL virtual-texturing demo (client-web/src/vt.html) flown in headless Chromium against a
// real vtex serve: frame time and pages streamed per second of flight, BC7 and RGBA pages, the
// server's cache cold then warm, beside a baseline from the same run — the same renderer at a
// fixed camera once every page it needs is resident (feedback and colour passes, no streaming).
//
//   flock /tmp/vtex-bench.lock node bench/vt-demo/run.mjs [frames] [--screenshot docs/vt-demo.png]
//
// Writes bench/results/vt-demo-<date>.md. Chromium's WebGL here is software (SwiftShader): the
// frame times are the CPU's, not a GPU's.
import { writeFileSync } from 'node:fs';
import { loadavg, cpus } from 'node:os';
import { join } from 'node:path';
import { launchBrowser, ROOT, startServer } from '../../tests/browser/lib.mjs';
import { mean, quantile } from '../stats.mjs';

const args = process.argv.slice(2);
const frames = Number(args.find((a) => /^\d+$/.test(a)) || 240);
const shotAt = args.includes('--screenshot') ? args[args.indexOf('--screenshot') + 1] : null;
const VIEW = { width: 1280, height: 720 };
const START = '50000,50000,220,0,20';

const server = await startServer();
const browser = await launchBrowser(VIEW);
const load = [loadavg()[0]];

/** Runs the demo with `query` to its last frame; its figures over frames `from`… */
async function run(name, query, from = 1) {
  const page = await browser.context.newPage();
  await page.goto(`${server.url}/vt.html?${query}&frames=${frames}&debug`);
  await page.waitForFunction(() => window.vtDemo && (window.vtDemo.error || window.vtDemo.state.done), null, { timeout: 900_000, polling: 250 });
  const s = await page.evaluate(() => {
    const { state, cache } = window.vtDemo;
    return { error: state.error, frameMs: state.frameMs, cpuMs: state.cpuMs, log: state.log, stats: state.stats, resident: cache.size };
  });
  if (s.error) throw new Error(`${name}: ${s.error}`);
  if (shotAt && name === 'flight, BC7, server warm') await page.screenshot({ path: join(ROOT, shotAt) });
  await page.close();
  load.push(loadavg()[0]);
  const frameMs = s.frameMs.slice(from);
  const seconds = s.frameMs.slice(1).reduce((a, b) => a + b, 0) / 1000;
  const streamed = s.log.filter((e) => e.event === 'resident' && e.frame > 0).length;
  const row = {
    name,
    frameMean: mean(frameMs),
    frameP50: quantile(frameMs, 0.5),
    frameP95: quantile(frameMs, 0.95),
    cpuMean: mean(s.cpuMs.slice(from)),
    streamed,
    pagesPerSecond: streamed / seconds,
    mbPerSecond: s.stats.bytes / 1e6 / seconds,
    metatiles: s.stats.metatiles,
    unusedShare: s.stats.unused / s.stats.bytes,
    evicted: s.log.filter((e) => e.event === 'evict').length,
  };
  console.log(JSON.stringify(row));
  return row;
}

const rows = [];
try {
  rows.push(await run('flight, BC7, server cold', 'format=bc7'));
  rows.push(await run('flight, BC7, server warm', 'format=bc7'));
  rows.push(await run('flight, RGBA, server cold', 'format=rgba'));
  rows.push(await run('flight, RGBA, server warm', 'format=rgba'));
  // The baseline: the first frames stream the start view's pages, the second half draws them.
  rows.push(await run('baseline: fixed camera, all resident, BC7', `format=bc7&camera=${START}`, Math.floor(frames / 2)));
} finally {
  await browser.close();
  await server.stop();
}

const f = (v, d = 1) => v.toFixed(d);
const md = [
  `# WebGL virtual-texturing demo: frame time and pages streamed (${new Date().toISOString().slice(0, 10)})`,
  '',
  `\`flock /tmp/vtex-bench.lock node bench/vt-demo/run.mjs ${frames}\` — ${frames} frames at ${VIEW.width}×${VIEW.height}, headless Chromium ` +
    `(software WebGL, SwiftShader), ${cpus().length} cores shared with other builds, load average ${load.map((l) => f(l)).join(' → ')}. ` +
    'Pages 128² + 4 px borders, fetched alone or as their page metatile (4 × 4 pages) where half of one is wanted (a metatile’s pages not asked for are received, not used); the flight moves 20 texels a frame at 220 texels above the ' +
    'Pebbles chaos mosaic 100k (the same path in every run); the atlas holds 256 pages.',
  '',
  '| run | frame ms mean | p50 | p95 | CPU ms/frame | pages streamed | metatiles fetched | pages/s of flight | MB/s | bytes not asked for | evictions |',
  '|---|---|---|---|---|---|---|---|---|---|---|',
  ...rows.map((r) => `| ${r.name} | ${f(r.frameMean)} | ${f(r.frameP50)} | ${f(r.frameP95)} | ${f(r.cpuMean)} | ${r.streamed} | ${r.metatiles} | ${f(r.pagesPerSecond)} | ${f(r.mbPerSecond, 2)} | ${f(100 * r.unusedShare, 0)} % | ${r.evicted} |`),
  '',
].join('\n');
const out = join(ROOT, 'bench', 'results', `vt-demo-${new Date().toISOString().slice(0, 10)}.md`);
writeFileSync(out, md);
console.log(md);
console.log(`wrote ${out}`);
