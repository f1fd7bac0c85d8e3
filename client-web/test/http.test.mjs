// How the pages and Workers read vtex's answers (client-web/src/shared/http.js): a refusal's
// reason from its JSON `error` or its text, and errors that name what was asked for.
import test from 'node:test';
import assert from 'node:assert/strict';
import { errorText, fetchOk, getJson } from '../src/shared/http.js';

const bytes = (s) => new TextEncoder().encode(s);

test('the reason of an error body: its JSON error, else its start as text', () => {
  assert.equal(errorText(bytes('{"error":"texture abc not found"}')), 'texture abc not found');
  assert.equal(errorText(bytes('<html>Bad Gateway</html>')), '<html>Bad Gateway</html>');
  assert.equal(errorText(bytes('x'.repeat(500))).length, 200);
  assert.equal(errorText(bytes('')), '');
});

/** Runs `f` with `fetch` answering `answer(url, init)`. */
async function withFetch(answer, f) {
  const real = globalThis.fetch;
  globalThis.fetch = async (url, init) => answer(url, init);
  try {
    return await f();
  } finally {
    globalThis.fetch = real;
  }
}

test('a success is answered as it is; a refusal names what, the status, the URL and the reason', async () => {
  await withFetch(
    () => new Response('{"textures":[]}', { status: 200 }),
    async () => assert.deepEqual(await getJson('api/v1/textures'), { textures: [] }),
  );
  await withFetch(
    () => new Response('{"error":"no such model"}', { status: 404 }),
    async () => {
      await assert.rejects(getJson('api/v1/models/x', 'the model'), { message: 'the model: HTTP 404 for api/v1/models/x – no such model' });
      await assert.rejects(fetchOk('api/v1/models/x'), { message: 'HTTP 404 for api/v1/models/x – no such model' });
    },
  );
  await withFetch(
    () => new Response('', { status: 502 }),
    async () => await assert.rejects(fetchOk(`u${'v'.repeat(300)}`), { message: `HTTP 502 for u${'v'.repeat(199)}…` }),
  );
});

test('a failed fetch names the URL; an abort stays an AbortError', async () => {
  await withFetch(
    () => {
      throw new TypeError('Failed to fetch');
    },
    async () => await assert.rejects(fetchOk('vtex_synth_lcm.wasm', 'the synthesis module'), { message: 'the synthesis module: could not fetch vtex_synth_lcm.wasm: Failed to fetch' }),
  );
  await withFetch(
    () => {
      throw new DOMException('The operation was aborted.', 'AbortError');
    },
    async () => await assert.rejects(fetchOk('api/v1/textures/x/tiles'), { name: 'AbortError' }),
  );
});
