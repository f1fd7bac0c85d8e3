// Open + first tile, native against WebAssembly in node, for every demo: the time from an
// encoding's bytes to an opened texture and to the RGBA of a first tile on it (the centre tile of
// level 0), as a client's Worker pays it.
// Native runs the module's own code (wasm/examples/first_tile.rs, which also writes the
// bundles); the module runs through client-web/src/shared/vtex-synth.js, a fresh instance a run.
//
// Usage: node bench/wasm/first-tile.mjs [RUNS]   (median of RUNS, 3 by default)
// Needs: scripts/build-wasm (each demo runs through its model's module)
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { instantiate } from '../../client-web/src/shared/vtex-synth.js';
import { ROOT, modulePath } from '../../tests/wasm/modules.mjs';

const TILE_SIZE = 256;
const runs = Number(process.argv[2] ?? 3);

const dir = mkdtempSync(join(tmpdir(), 'vtex-first-tile-'));
try {
  const native = execFileSync(
    'cargo',
    ['run', '--quiet', '--release', '--locked', '-p', 'vtex-synth-wasm', '--example', 'first_tile', '--', dir, String(runs)],
    { cwd: ROOT, encoding: 'utf8', stdio: ['ignore', 'pipe', 'inherit'] },
  );
  const modules = new Map();
  const median = (xs) => xs.sort((a, b) => a - b)[Math.floor(xs.length / 2)];
  const rows = [];
  for (const demo of native.trim().split('\n').map((line) => JSON.parse(line))) {
    const bytes = readFileSync(join(dir, demo.bundle));
    if (!modules.has(demo.model)) modules.set(demo.model, await WebAssembly.compile(readFileSync(modulePath(demo.model))));
    const module = modules.get(demo.model);
    for (const tile of demo.tiles) {
      const [open, total] = [[], []];
      for (let i = 0; i < runs; i++) {
        const synth = await instantiate(module);
        const start = performance.now();
        const tex = synth.open(bytes, TILE_SIZE);
        open.push(performance.now() - start);
        tex.renderTile(tile.level, tile.tx, tile.ty);
        total.push(performance.now() - start);
        tex.close();
      }
      rows.push({
        model: demo.model,
        name: demo.name,
        tile: `${tile.level}/${tile.tx}/${tile.ty}`,
        native: [tile.open_ms, tile.ms],
        wasm: [median(open), median(total)],
      });
    }
  }
  console.log(`open + first tile, median of ${runs} runs, ${TILE_SIZE}² tiles (level/tx/ty); ms, of which opening\n`);
  console.log('| model | demo | tile | native ms (open) | wasm ms (open) | wasm / native |');
  console.log('|---|---|---|---:|---:|---:|');
  const ms = ([open, total]) => `${total.toFixed(1)} (${open.toFixed(1)})`;
  for (const r of rows) {
    console.log(`| ${r.model} | ${r.name} | ${r.tile} | ${ms(r.native)} | ${ms(r.wasm)} | ${(r.wasm[1] / r.native[1]).toFixed(1)} |`);
  }
} finally {
  rmSync(dir, { recursive: true, force: true });
}
