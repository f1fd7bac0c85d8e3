// How the pages and Workers read vtex's answers (client-web/src/shared/http.js): a refusal's
// reason from its JSON `error` or its text, and errors that name what was asked for.
import test from 'node:test';
import assert from 'node:assert/strict';
import { errorText, fetchOk, getJson, retryDelay, RETRIES_503 } from '../src/shared/http.js';

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

test('a read answered 503 is asked again after its Retry-After; a write is not', async () => {
  let calls = 0;
  const busy = () => new Response('{"error":"busy"}', { status: 503, headers: { 'retry-after': '0' } });
  await withFetch(
    () => (++calls < 3 ? busy() : new Response('ok', { status: 200 })),
    async () => assert.equal(await (await fetchOk('api/v1/textures/x/tiles/0/0/0.png')).text(), 'ok'),
  );
  assert.equal(calls, 3);
  calls = 0;
  await withFetch(
    () => (calls++, busy()),
    async () => await assert.rejects(fetchOk('t'), { message: 'HTTP 503 for t – busy' }),
  );
  assert.equal(calls, 1 + RETRIES_503, 'asked again three times, then the 503 is the answer');
  calls = 0;
  await withFetch(
    () => (calls++, busy()),
    async () => await assert.rejects(fetchOk('api/v1/textures', 'the upload', { method: 'POST' }), { message: /HTTP 503/ }),
  );
  assert.equal(calls, 1, 'a write is not sent again');
});

test('an abort while waiting to ask again is an AbortError, and nothing more is sent', async () => {
  let calls = 0;
  const controller = new AbortController();
  await withFetch(
    () => {
      calls++;
      setTimeout(() => controller.abort(), 10);
      return new Response('', { status: 503, headers: { 'retry-after': '3' } });
    },
    async () => await assert.rejects(fetchOk('t', '', { signal: controller.signal }), { name: 'AbortError' }),
  );
  assert.equal(calls, 1);
});

test('Retry-After in seconds or as a date, within 0–5 s; 1 s when absent or unreadable', () => {
  assert.equal(retryDelay('2'), 2);
  assert.equal(retryDelay('0'), 0);
  assert.equal(retryDelay('120'), 5);
  assert.equal(retryDelay(null), 1);
  assert.equal(retryDelay('soon'), 1);
  const inThree = new Date(Date.now() + 3000).toUTCString();
  assert.ok(Math.abs(retryDelay(inThree) - 3) <= 1, retryDelay(inThree));
  assert.equal(retryDelay(new Date(Date.now() - 60000).toUTCString()), 0);
});
