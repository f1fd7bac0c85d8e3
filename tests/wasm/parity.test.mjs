// The WebAssembly build of vtex-synth renders exactly the native bytes: the same
// probe of every demo texture, hashed, native (cargo run --bin parity) against wasm32 in Node.
// Needs: cargo build -p vtex-synth-wasm --lib --target wasm32-unknown-unknown --release
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const ROOT = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
const WASM = join(ROOT, 'target', 'wasm32-unknown-unknown', 'release', 'vtex_synth_wasm.wasm');

test('wasm32 renders every demo probe byte for byte like native', async () => {
  const { instance } = await WebAssembly.instantiate(readFileSync(WASM), {});
  const ptr = instance.exports.vtex_probe();
  const memory = new Uint8Array(instance.exports.memory.buffer);
  const end = memory.indexOf(0, ptr);
  const wasm = new TextDecoder().decode(memory.subarray(ptr, end)).split('\n');
  const native = execFileSync('cargo', ['run', '--quiet', '--release', '--locked', '-p', 'vtex-synth-wasm', '--bin', 'parity'], {
    cwd: ROOT,
    encoding: 'utf8',
    maxBuffer: 1 << 24,
  })
    .trim()
    .split('\n');
  assert.ok(native.length >= 9 * 10, `only ${native.length} probes`);
  assert.equal(wasm.length, native.length);
  const differing = native.map((h, i) => (h === wasm[i] ? null : i)).filter((i) => i !== null);
  assert.deepEqual(differing, [], `probes differing between native and wasm32: ${differing.join(', ')}`);
});
