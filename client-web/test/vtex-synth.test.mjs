// The wrapper of the synthesis module (src/shared/vtex-synth.js) against a stand-in for its exports:
// a trap becomes a SynthError carrying the panic's message, and the instance is not used again.
// (tests/wasm/api.test.mjs runs the wrapper over the real module.)
import test from 'node:test';
import assert from 'node:assert/strict';
import { Synth, SynthError } from '../src/shared/vtex-synth.js';

/** Exports whose vtex_open traps after "panicking" with `message`. */
function trappingExports(message) {
  const memory = new WebAssembly.Memory({ initial: 1 });
  const bytes = new TextEncoder().encode(message);
  let panicked = false;
  return {
    memory,
    vtex_init() {},
    vtex_input: () => 1024,
    vtex_open() {
      new Uint8Array(memory.buffer, 0, bytes.length).set(bytes);
      panicked = true;
      throw new WebAssembly.RuntimeError('unreachable');
    },
    vtex_panic_message: () => 0,
    vtex_panic_message_len: () => (panicked ? bytes.length : 0),
  };
}

test('a trap is a SynthError with the panic message, and the instance stops', () => {
  const synth = new Synth({ exports: trappingExports('panicked at synth/src/x.rs:1:1: index out of bounds') });
  assert.throws(() => synth.open(new Uint8Array(4)), (e) => e instanceof SynthError && /failed: panicked at .*index out of bounds/.test(e.message));
  assert.throws(() => synth.open(new Uint8Array(4)), /stopped after an earlier failure: panicked at/);
});

test('a trap without a panic message still names the trap', () => {
  const exports = trappingExports('');
  const synth = new Synth({ exports });
  assert.throws(() => synth.open(new Uint8Array(4)), /the synthesis module failed: unreachable/);
});

test('other exceptions pass through and do not stop the instance', () => {
  const exports = { ...trappingExports('x'), vtex_input: () => { throw new RangeError('out of memory'); } };
  const synth = new Synth({ exports });
  assert.throws(() => synth.open(new Uint8Array(4)), RangeError);
  assert.equal(synth.failure, null);
});
