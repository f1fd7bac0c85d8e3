// The debugging hooks' switch (client-web/src/shared/debug.js): a page exposes its hooks only when
// its URL asks with `debug`, and the address the viewer writes keeps the parameter.
import test from 'node:test';
import assert from 'node:assert/strict';
import { debugAsked, expose, keepDebug } from '../src/shared/debug.js';

test('the hooks are asked for by a debug parameter, with or without a value', () => {
  assert.equal(debugAsked(''), false);
  assert.equal(debugAsked('?texture=abc&zoom=1'), false);
  assert.equal(debugAsked('?debug'), true);
  assert.equal(debugAsked('?texture=abc&debug'), true);
  assert.equal(debugAsked('?debug=1'), true);
});

test('without the parameter nothing is exposed (Node has no location: not asked)', () => {
  expose('vtexTestHook', {});
  assert.equal(globalThis.vtexTestHook, undefined);
});

test('the address written keeps debug when it was asked for, and only then', () => {
  assert.equal(keepDebug('?texture=abc&zoom=1', false), '?texture=abc&zoom=1');
  assert.equal(keepDebug('?texture=abc&zoom=1', true), '?texture=abc&zoom=1&debug');
  assert.equal(keepDebug('?', true), '?debug');
  assert.equal(keepDebug('', true), '?debug');
  assert.equal(keepDebug('?debug&texture=abc', true), '?debug&texture=abc', 'not twice');
});
