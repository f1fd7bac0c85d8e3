// The size gate of the modules browsers download: every model's module, as scripts/build-wasm
// builds it, within its budget once brotli-compressed as the viewer's build sends it
// (client-web/build.mjs: quality 11, window 2^24). Prints each module's raw, gzip and brotli
// sizes, so CI's log shows them.
// Needs: scripts/build-wasm
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { brotliCompressSync, constants, gzipSync } from 'node:zlib';
import { MODELS, modulePath } from './modules.mjs';

/** Brotli bytes a module may take: what a client downloads before its first tile. */
const BUDGET = 150_000;

const brotli = (bytes) =>
  brotliCompressSync(bytes, {
    params: { [constants.BROTLI_PARAM_QUALITY]: 11, [constants.BROTLI_PARAM_LGWIN]: 24, [constants.BROTLI_PARAM_SIZE_HINT]: bytes.length },
  }).length;

test("every model's module is within the budget with brotli", () => {
  assert.ok(MODELS.length >= 5, `only ${MODELS.length} models in wasm/Cargo.toml`);
  const over = [];
  for (const model of MODELS) {
    const bytes = readFileSync(modulePath(model));
    const size = { raw: bytes.length, gzip: gzipSync(bytes, { level: 9 }).length, brotli: brotli(bytes) };
    console.log(`${model}: ${size.raw} B raw, ${size.gzip} B gzip -9, ${size.brotli} B brotli (budget ${BUDGET} B)`);
    if (size.brotli > BUDGET) over.push(`${model}: ${size.brotli} B, budget ${BUDGET} B`);
  }
  assert.deepEqual(over, [], 'modules over their budget with brotli');
});
