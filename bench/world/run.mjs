// The 3D world (client-web/src/world.html) walked along its scripted path (`?path=bench`) in
// headless Chromium against a real vtex serve, once per page source — synthesized in the browser
// from the encodings, and fetched from the server as JPEG and as BC7 KTX2 pages — each with a
// fresh browser profile (an empty HTTP cache) and a fresh server: bytes on the wire by kind
// (encodings, module, pages), the time to the first complete frame, the share of the pages each
// step of the path needs that are resident (the others are drawn from a coarser level), and the
// frame times over the path. Loopback, no network emulation (bench/bandwidth.mjs walks it under
// throttled networks too, with the same session: bench/bandwidth/sessions.mjs).
//
//   flock /tmp/vtex-bench.lock node bench/world/run.mjs [steps] [--screenshot docs/world.png]
//
// Writes bench/results/world-<date>.json and prints a Markdown table. Chromium's WebGL here is
// software (SwiftShader): frame times are the CPU's, not a GPU's.
import { writeFileSync } from 'node:fs';
import { cpus, loadavg } from 'node:os';
import { join } from 'node:path';
import { ROOT } from '../../tests/browser/lib.mjs';
import { worldWalk } from '../bandwidth/sessions.mjs';
import { mean, quantile } from '../stats.mjs';

const args = process.argv.slice(2);
const steps = Number(args.find((a) => /^\d+$/.test(a)) || 120);
const shotAt = args.includes('--screenshot') ? args[args.indexOf('--screenshot') + 1] : null;
const VIEW = { width: 1280, height: 720 };
const MODES = ['client', 'jpg', 'ktx2'];

const rows = [];
for (const mode of MODES) {
  const loadBefore = loadavg()[0];
  // The walk's last view (back at its start), the overlay showing the walk's bytes.
  const screenshot = shotAt && mode === 'client' ? join(ROOT, shotAt) : null;
  const r = await worldWalk({ mode, profile: 'loopback', size: VIEW, steps, capMs: 1_800_000, screenshot });
  const s = r.stats;
  // The frames of the walk: after the first complete one (the camera waits for it at the start).
  const walked = s.frameMs.slice(s.frames - s.steps);
  const row = {
    mode,
    steps: s.steps,
    firstCompleteS: s.firstComplete / 1000,
    residentShare: mean(s.residentShare),
    bytes: r.bytes,
    requests: r.requests,
    frameMean: mean(walked),
    frameP50: quantile(walked, 0.5),
    frameP95: quantile(walked, 0.95),
    cpuMean: mean(s.cpuMs.slice(s.frames - s.steps)),
    load: [loadBefore, loadavg()[0]],
  };
  console.log(JSON.stringify(row));
  rows.push(row);
}

const date = new Date().toISOString().slice(0, 16).replace(':', '');
const out = join(ROOT, 'bench', 'results', `world-${date}.json`);
writeFileSync(out, JSON.stringify({ command: `node bench/world/run.mjs ${args.join(' ')}`, cores: cpus().length, view: VIEW, rows }, null, 2));
const kB = (b) => (b / 1e3).toFixed(0);
console.log('\n| pages | encodings kB | module kB | pages kB (requests) | first complete frame | pages needed that were resident, mean over the steps | frame mean / p50 / p95 ms | load (1 min) |');
console.log('|---|---|---|---|---|---|---|---|');
for (const r of rows) {
  console.log(
    `| ${r.mode} | ${kB(r.bytes.encoding)} | ${kB(r.bytes.module)} | ${kB(r.bytes.pixels)} (${r.requests.pixels}) | ${r.firstCompleteS.toFixed(2)} s | ${(100 * r.residentShare).toFixed(1)} % | ${r.frameMean.toFixed(0)} / ${r.frameP50.toFixed(0)} / ${r.frameP95.toFixed(0)} | ${r.load.map((l) => l.toFixed(1)).join(' → ')} |`,
  );
}
console.log(`\nwritten ${out}`);
