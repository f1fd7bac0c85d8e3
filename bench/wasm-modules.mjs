// The per-model WebAssembly modules against the single module that held every model: each
// module's size (raw, gzip -9, brotli as the viewer's build makes it) and the time to render
// tiles of each model's first demo in Node, the baseline module and each candidate on the same
// bundles in the same run, alternating, so load drifts alike on both.
//
//   cargo run --release -p vtex-synth-wasm --bin reference -- DIR      (the demo bundles)
//   flock /tmp/vtex-bench.lock node bench/wasm-modules.mjs --bundles DIR --baseline ALL.wasm \
//        [--modules target/wasm-modules] [--modules OTHER_DIR …] [--rounds 5] [--json OUT]
//
// The tiles are the server's 256² tiles: `rounds` different ones of level 0 and of the middle
// level (row-major from the origin), so no tile is served from a model's cache; each module renders
// them in its own instance, opened once per demo; the figure is the median of the rounds.
import { readFileSync, writeFileSync } from 'node:fs';
import { loadavg } from 'node:os';
import { join } from 'node:path';
import { parseArgs } from 'node:util';
import { brotliCompressSync, constants, gzipSync } from 'node:zlib';
import { instantiate, moduleFile } from '../client-web/src/shared/vtex-synth.js';

const { values: args } = parseArgs({
  options: {
    bundles: { type: 'string' },
    baseline: { type: 'string' },
    modules: { type: 'string', multiple: true, default: ['target/wasm-modules'] },
    rounds: { type: 'string', default: '5' },
    json: { type: 'string' },
  },
});
if (!args.bundles || !args.baseline) throw new Error('usage: --bundles DIR --baseline ALL.wasm [--modules DIR …]');
const ROUNDS = Number(args.rounds);
const TILE = 256;

const sizes = (bytes) => ({
  raw: bytes.length,
  gzip: gzipSync(bytes, { level: 9 }).length,
  brotli: brotliCompressSync(bytes, {
    params: { [constants.BROTLI_PARAM_QUALITY]: 11, [constants.BROTLI_PARAM_LGWIN]: 24, [constants.BROTLI_PARAM_SIZE_HINT]: bytes.length },
  }).length,
});
const median = (xs) => [...xs].sort((a, b) => a - b)[xs.length >> 1];

/** Milliseconds to render the `n`th tile (row-major) of `level` of the open texture `tex`. */
function time(tex, level, n) {
  const columns = Math.ceil(Math.ceil(tex.info.width / 2 ** level) / TILE);
  const t0 = performance.now();
  tex.renderTile(level, n % columns, Math.floor(n / columns), 0);
  return performance.now() - t0;
}

const open = async (module, bundle) => (await instantiate(module)).open(bundle, TILE);

const reference = JSON.parse(readFileSync(join(args.bundles, 'reference.json'), 'utf8'));
const baselineBytes = readFileSync(args.baseline);
const baseline = await WebAssembly.compile(baselineBytes);
const result = { load: loadavg(), baseline: { file: args.baseline, ...sizes(baselineBytes) }, sets: [] };
for (const dir of args.modules) {
  const set = { dir, models: {} };
  for (const model of new Set(reference.demos.map((d) => d.info.model))) {
    const bytes = readFileSync(join(dir, moduleFile(model)));
    set.models[model] = { ...sizes(bytes), module: await WebAssembly.compile(bytes), tiles: [] };
  }
  result.sets.push(set);
}
const firstOfEachModel = reference.demos.filter((d, i, all) => all.findIndex((e) => e.info.model === d.info.model) === i);
for (const demo of firstOfEachModel) {
  const bundle = readFileSync(join(args.bundles, demo.bundle));
  const old = await open(baseline, bundle);
  const candidates = await Promise.all(result.sets.map((set) => open(set.models[demo.info.model].module, bundle)));
  for (const level of [0, demo.info.levels >> 1]) {
    const times = { old: [], sets: result.sets.map(() => []) };
    for (let r = 0; r < ROUNDS; r++) {
      times.old.push(time(old, level, r));
      candidates.forEach((tex, i) => times.sets[i].push(time(tex, level, r)));
    }
    result.sets.forEach((set, i) =>
      set.models[demo.info.model].tiles.push({ demo: demo.info.name, level, baseline_ms: median(times.old), ms: median(times.sets[i]) }),
    );
  }
}
console.log(`load average ${result.load.map((l) => l.toFixed(2)).join(' ')}`);
console.log(`baseline ${args.baseline}: ${result.baseline.raw} B raw, ${result.baseline.gzip} B gzip, ${result.baseline.brotli} B brotli`);
for (const set of result.sets) {
  console.log(`\n${set.dir}\n| model | raw | gzip -9 | brotli | tiles | render, baseline | render, this module | ratio |\n|---|---|---|---|---|---|---|---|`);
  for (const [model, m] of Object.entries(set.models)) {
    const old = m.tiles.reduce((s, t) => s + t.baseline_ms, 0);
    const now = m.tiles.reduce((s, t) => s + t.ms, 0);
    console.log(`| ${model} | ${m.raw} | ${m.gzip} | ${m.brotli} | ${m.tiles.length} | ${old.toFixed(1)} ms | ${now.toFixed(1)} ms | ${(now / old).toFixed(2)}× |`);
    delete m.module;
  }
}
if (args.json) writeFileSync(args.json, JSON.stringify(result, null, 2));
