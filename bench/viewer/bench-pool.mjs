// Pools the view times of several `bench.mjs --json FILE` runs, per pass: one run's p95 rests on
// its three slowest views of 60, and from run to run it moves by more than most changes do.
// Groups of runs (an A/B comparison) are separated by `--`.
//
//   node bench/viewer/bench-pool.mjs A1.json A2.json … [-- B1.json B2.json …] [--views N] [--fast MS] [--drawn]
//
// Times are to the end of the main-thread work of the frame that completed each view, raster
// included (bench.mjs `rasterTimes`); with --drawn, to its draw calls (`times`: the only figure
// in the JSON files of older versions of bench.mjs).
//
// For each group and pass: views pooled, mean, p50 / p75 / p90 / p95, views over the warm
// target (30 ms), each run's p95, and the machine reference (bench.mjs cpuReference: mean of
// the before and after figures of every run's pass; lower is a faster machine). With
// --views N, also the N warm-server views slowest on average, with their time in every run:
// the same view is often either one frame fast or one frame slow (a view is done in an
// animation frame), and which one depends on a millisecond or two. With --fast MS, each pass
// also split in two: the passes whose machine references, before and after, were both under
// MS (the machine at its fast speed throughout), and the rest.
import { readFileSync } from 'node:fs';
import { percentile } from '../../client-web/src/viewer/stats.js';

const argv = process.argv.slice(2);
let views = 0;
let fast = null;
let field = 'rasterTimes';
const groups = [[]];
for (let i = 0; i < argv.length; i++) {
  if (argv[i] === '--views') views = Number(argv[++i]);
  else if (argv[i] === '--drawn') field = 'times';
  else if (argv[i] === '--fast') fast = Number(argv[++i]);
  else if (argv[i] === '--') groups.push([]);
  else groups.at(-1).push(argv[i]);
}
if (groups.some((g) => g.length === 0) || !Number.isInteger(views) || views < 0 || (fast !== null && !(fast > 0))) {
  console.error('usage: node bench/viewer/bench-pool.mjs RUN.json … [-- RUN.json …] [--views N] [--fast MS] [--drawn]');
  process.exit(2);
}

const PASSES = [
  ['cold', 'cold'],
  ['warmServer', 'warm server'],
  ['warmBrowser', 'warm browser'],
  ['warmViewer', 'warm viewer'],
];
const WARM_TARGET_MS = 30;
const f = (v) => (Number.isFinite(v) ? v.toFixed(1) : '–');
const mean = (v) => v.reduce((a, b) => a + b, 0) / v.length;

const loaded = groups.map((files) =>
  files.map((file) => {
    const run = JSON.parse(readFileSync(file, 'utf8'));
    if (!run.warmServer || !run.warmServer[field]) {
      console.error(`${file}: no ${field} (a run made before the bench timed views to the raster? try --drawn)`);
      process.exit(2);
    }
    return run;
  }),
);
/** A pass's view times at the chosen end point. */
const timesOf = (pass) => pass[field];
console.log('| group | pass | runs | views | mean | p50 | p75 | p90 | p95 | > 30 ms | per-run p95 | machine reference ms |');
console.log('|---|---|---|---|---|---|---|---|---|---|---|---|');
/** Whether a pass ran with the machine at its fast speed throughout (--fast). */
const isFast = (pass) => (pass.cpuReferenceMs || []).length === 2 && pass.cpuReferenceMs.every((ms) => ms < fast);
loaded.forEach((runs, g) => {
  for (const [key, name] of PASSES) {
    const all = runs.map((r) => r[key]).filter(Boolean);
    const subsets =
      fast === null
        ? [[name, all]]
        : [
            [name, all],
            [`${name}, reference < ${fast} ms`, all.filter(isFast)],
            [`${name}, the rest`, all.filter((p) => !isFast(p))],
          ];
    for (const [label, passes] of subsets) row(g, label, passes);
  }
});

/** One line of the table: the passes `passes` of group `g`, pooled. */
function row(g, label, passes) {
  if (!passes.length) return;
  const t = passes.flatMap(timesOf);
  const over = t.filter((x) => x > WARM_TARGET_MS).length;
  const reference = passes.flatMap((p) => p.cpuReferenceMs || []);
  const perRun = passes.map((p) => f(percentile(timesOf(p), 0.95))).join(', ');
  console.log(
    `| ${String.fromCharCode(65 + g)} | ${label} | ${passes.length} | ${t.length} | ${f(mean(t))} | ${f(percentile(t, 0.5))} | ${f(percentile(t, 0.75))} | ${f(percentile(t, 0.9))} | **${f(percentile(t, 0.95))}** | ${over} | ${perRun} | ${reference.length ? f(mean(reference)) : '–'} |`,
  );
}

if (views > 0) {
  loaded.forEach((runs, g) => {
    const passes = runs.map((r) => r.warmServer).filter(Boolean);
    if (!passes.length) return;
    const n = Math.min(...passes.map((p) => timesOf(p).length));
    const rows = Array.from({ length: n }, (_, i) => {
      const t = passes.map((p) => timesOf(p)[i]);
      return { i, tiles: passes[0].tiles[i], mean: mean(t), t };
    }).sort((a, b) => b.mean - a.mean);
    console.log(`\ngroup ${String.fromCharCode(65 + g)}, warm server: the ${views} views slowest on average (view index from 0, tiles, mean ms, ms in each run)`);
    for (const r of rows.slice(0, views)) console.log(`  view ${r.i}: ${r.tiles} tiles, mean ${f(r.mean)}: ${r.t.map((x) => x.toFixed(0)).join(' ')}`);
  });
}
