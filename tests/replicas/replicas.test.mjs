// The deployment of docker/compose.yaml, proven on loopback: 3 `vtex serve` on one data
// directory behind Debian's nginx running docker/nginx.conf (see topology.mjs).
import assert from 'node:assert/strict';
import http from 'node:http';
import { after, before, test } from 'node:test';
import zlib from 'node:zlib';
import { startTopology } from './topology.mjs';

const TOKEN = 'replicas-test-token';
let topo;
let texture;

before(async () => {
  topo = await startTopology({ replicas: 3, env: { VTEX_WRITE_TOKEN: TOKEN } });
  const list = await (await fetch(`${topo.url}/api/v1/textures`)).json();
  // The 100k chaos mosaic: many cheap tiles, so the load below misses every cache.
  texture = list.textures.filter((t) => t.model === 'chaos-mosaic').sort((a, b) => b.width - a.width)[0];
  assert.ok(texture, 'a chaos mosaic demo is served');
});

after(async () => {
  await topo?.stop();
});

const tilePath = (id, l, x, y, f = 'png') => `/api/v1/textures/${id}/tiles/${l}/${x}/${y}.${f}`;

async function get(url, init) {
  const r = await fetch(url, init);
  return { status: r.status, headers: r.headers, body: Buffer.from(await r.arrayBuffer()) };
}

test('every replica serves the same bytes for a tile, and so does nginx', async () => {
  for (const [l, x, y] of [[0, 17, 3], [4, 2, 1], [9, 0, 0]]) {
    const path = tilePath(texture.id, l, x, y);
    const answers = await Promise.all([...topo.replicas.map((r) => r.url), topo.url].map((b) => get(b + path)));
    for (const a of answers) {
      assert.equal(a.status, 200, path);
      assert.ok(a.body.equals(answers[0].body), `${path}: bytes differ between replicas`);
    }
  }
});

test('nginx answers a repeated tile from its cache', async () => {
  const url = topo.url + tilePath(texture.id, 1, 40, 41, 'webp');
  const first = await get(url);
  const again = await get(url);
  assert.equal(first.status, 200);
  assert.equal(first.headers.get('x-cache-status'), 'MISS');
  assert.equal(again.headers.get('x-cache-status'), 'HIT');
  assert.ok(again.body.equals(first.body));
  // What vtex does not mark cacheable is never cached: the list, errors.
  const list = `${topo.url}/api/v1/textures/${'f'.repeat(64)}`;
  await get(list);
  assert.notEqual((await get(list)).headers.get('x-cache-status'), 'HIT');
});

/** A GET through node:http, whose headers are exactly `headers` (fetch adds Accept-Encoding
 * and decodes the body): the body as it came over the wire. */
function rawGet(url, headers) {
  return new Promise((resolve, reject) => {
    http
      .get(url, { headers, agent: false }, (res) => {
        const chunks = [];
        res.on('data', (c) => chunks.push(c));
        res.on('end', () => resolve({ status: res.statusCode, headers: res.headers, body: Buffer.concat(chunks) }));
      })
      .on('error', reject);
  });
}

test('what nginx passes on, a CDN in front may cache: Cache-Control, ETag and Vary, each encoding apart', async () => {
  // A metatile, the viewer's tile traffic: one immutable URL for every viewer.
  const block = await rawGet(`${topo.url}/api/v1/textures/${texture.id}/metatiles/2/3/4.webp`, {});
  assert.equal(block.status, 200);
  assert.equal(block.headers['cache-control'], 'public, max-age=31536000, immutable');
  assert.match(block.headers.etag, /^"[^"]+"$/);
  // A raw tile is compressed for a client that accepts it: the answer names what it varies by,
  // and nginx's cache keeps the encodings apart (a client that accepts none gets no gzip).
  const raw = `${topo.url}${tilePath(texture.id, 1, 7, 9, 'rgba')}`;
  const gzip = await rawGet(raw, { 'accept-encoding': 'gzip' });
  assert.equal(gzip.status, 200);
  assert.equal(gzip.headers['content-encoding'], 'gzip');
  assert.match(gzip.headers.vary, /accept-encoding/i);
  assert.equal(gzip.headers['cache-control'], 'public, max-age=31536000, immutable');
  for (const attempt of ['first', 'again']) {
    const plain = await rawGet(raw, {});
    assert.equal(plain.headers['content-encoding'], undefined, `${attempt}: gzip served to a client that accepts none`);
    assert.ok(plain.body.equals(zlib.gunzipSync(gzip.body)), `${attempt}: identity bytes differ`);
  }
  assert.equal((await rawGet(raw, { 'accept-encoding': 'gzip' })).headers['x-cache-status'], 'HIT');
});

test('writes through nginx need the token; an upload through nginx is served by all three', async () => {
  const target = `${topo.url}/api/v1/textures/${texture.id}`;
  const patch = (auth) =>
    fetch(target, {
      method: 'PATCH',
      headers: { 'content-type': 'application/json', ...(auth ? { authorization: auth } : {}) },
      body: JSON.stringify({ name: 'renamed through nginx' }),
    });
  for (const auth of [null, 'Bearer wrong']) {
    const r = await patch(auth);
    assert.equal(r.status, 401);
    assert.match((await r.json()).error, /write token/);
  }
  const bundle = await get(`${topo.url}/api/v1/textures/${texture.id}/encoding`);
  const post = await fetch(`${topo.url}/api/v1/textures`, {
    method: 'POST',
    headers: { 'content-type': 'application/octet-stream' },
    body: bundle.body,
  });
  assert.equal(post.status, 401);

  const made = await patch(`Bearer ${TOKEN}`);
  assert.equal(made.status, 201);
  const { id } = await made.json();
  const path = tilePath(id, 3, 5, 6);
  const answers = await Promise.all(topo.replicas.map((r) => get(r.url + path)));
  for (const a of answers) {
    assert.equal(a.status, 200, a.body.toString().slice(0, 200));
    assert.ok(a.body.equals(answers[0].body));
  }
  for (const r of topo.replicas) {
    const deadline = Date.now() + 10_000;
    for (;;) {
      const ids = (await (await fetch(`${r.url}/api/v1/textures`)).json()).textures.map((t) => t.id);
      if (ids.includes(id)) break;
      assert.ok(Date.now() < deadline, `${r.url} does not list ${id}`);
      await new Promise((res) => setTimeout(res, 50));
    }
  }
});

test('killing a replica under load loses no request', async (t) => {
  const total = 1500;
  const concurrency = 12;
  const killAt = 400;
  let next = 0;
  let done = 0;
  let killedAt = null;
  const failures = [];
  const t0 = performance.now();
  const victim = topo.replicas[1];
  async function worker() {
    while (next < total) {
      const i = next++;
      // Distinct level-0 tiles: every one misses nginx's cache and reaches a replica.
      const url = topo.url + tilePath(texture.id, 0, 100 + (i % 50), 200 + Math.floor(i / 50), 'jpg');
      try {
        const r = await get(url);
        if (r.status !== 200 || r.body.length === 0) failures.push(`${r.status} ${url}`);
      } catch (e) {
        failures.push(`${e.cause?.code || e.message} ${url}`);
      }
      done++;
      if (done === killAt) {
        victim.proc.kill('SIGKILL');
        killedAt = done;
      }
    }
  }
  await Promise.all(Array.from({ length: concurrency }, worker));
  const seconds = (performance.now() - t0) / 1000;
  t.diagnostic(`${total} requests in ${seconds.toFixed(2)} s (${(total / seconds).toFixed(0)}/s), replica killed after ${killedAt}`);
  assert.equal((await victim.exited).signal, 'SIGKILL');
  assert.deepEqual(failures, []);
  // nginx did meet the dead replica, and retried those requests on the next one.
  const retried = topo.accessLog().split('\n').filter((l) => l.includes(`upstream=${victim.addr}, `));
  assert.ok(retried.length > 0, 'no request was retried on another replica');
  t.diagnostic(`${retried.length} requests retried on another replica`);
});

test('SIGTERM drains a request in flight, and nginx serves on', async () => {
  const replica = topo.replicas[2];
  const region = `${replica.url}/api/v1/textures/${texture.id}/region?level=0&x=7000&y=9000&w=2048&h=2048&format=png`;
  const pending = get(region);
  await new Promise((r) => setTimeout(r, 150));
  replica.proc.kill('SIGTERM');
  const answer = await pending;
  assert.equal(answer.status, 200);
  assert.ok(answer.body.subarray(0, 8).equals(Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a])));
  assert.deepEqual(await replica.exited, { code: 0, signal: null });
  // One replica of three is left: every request is still answered.
  for (let i = 0; i < 60; i++) {
    const r = await get(topo.url + tilePath(texture.id, 2, i, 7, 'jpg'));
    assert.equal(r.status, 200);
  }
});
