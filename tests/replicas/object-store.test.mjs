// Replicas that share nothing but a bucket: 3 `vtex serve --store s3://…`, each with an empty
// data directory of its own, behind nginx running docker/nginx.conf (topology.mjs), on a real
// S3-compatible object store started here (Garage, garage.mjs).
import assert from 'node:assert/strict';
import { after, before, test } from 'node:test';
import { startGarage } from './garage.mjs';
import { startTopology } from './topology.mjs';

const TOKEN = 'object-store-test-token';
const PREFIX = 'encodings';
// Short, so that the test sees the list follow and the deadline pass quickly.
const POLL_SECS = 1;
const TIMEOUT_SECS = 2;
let garage;
let topo;
let texture;

before(async () => {
  garage = await startGarage();
  topo = await startTopology({
    replicas: 3,
    store: `s3://${garage.bucket}/${PREFIX}`,
    env: { ...garage.env, VTEX_WRITE_TOKEN: TOKEN },
    args: ['--store-poll-secs', `${POLL_SECS}`, '--store-timeout-secs', `${TIMEOUT_SECS}`],
  });
  const list = await (await fetch(`${topo.url}/api/v1/textures`)).json();
  texture = list.textures.filter((t) => t.model === 'chaos-mosaic').sort((a, b) => b.width - a.width)[0];
  assert.ok(texture, 'a chaos mosaic demo is served');
});

after(async () => {
  await topo?.stop();
  await garage?.stop();
});

const tilePath = (id, l, x, y, f = 'png') => `/api/v1/textures/${id}/tiles/${l}/${x}/${y}.${f}`;
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function get(url, init) {
  const r = await fetch(url, init);
  return { status: r.status, headers: r.headers, body: Buffer.from(await r.arrayBuffer()) };
}

/** A new texture made through `base` (a replica's URL): the demo renamed. */
function rename(base, name) {
  return fetch(`${base}/api/v1/textures/${texture.id}`, {
    method: 'PATCH',
    headers: { 'content-type': 'application/json', authorization: `Bearer ${TOKEN}` },
    body: JSON.stringify({ name }),
  });
}

async function listed(base) {
  return (await (await fetch(`${base}/api/v1/textures`)).json()).textures.map((t) => t.id).sort();
}

/** Waits until `check()` holds, for at most `ms`. */
async function eventually(what, check, ms = 10_000) {
  const deadline = Date.now() + ms;
  while (!(await check())) {
    assert.ok(Date.now() < deadline, `${what}: not within ${ms} ms`);
    await sleep(100);
  }
}

test('every replica starts on the bucket alone and lists the same textures', async () => {
  const lists = await Promise.all(topo.replicas.map((r) => listed(r.url)));
  assert.ok(lists[0].length > 3, 'the demos were written to the bucket');
  for (const l of lists) assert.deepEqual(l, lists[0]);
});

test('an upload through one replica is served by all at once, byte for byte', async () => {
  const made = await rename(topo.replicas[0].url, 'uploaded through replica 0');
  assert.equal(made.status, 201);
  const { id } = await made.json();
  // No poll waited for: a replica that does not know the id looks in the bucket.
  for (const [l, x, y] of [[0, 3, 4], [5, 1, 2]]) {
    const path = tilePath(id, l, x, y);
    const answers = await Promise.all([...topo.replicas.map((r) => r.url), topo.url].map((b) => get(b + path)));
    for (const a of answers) {
      assert.equal(a.status, 200, a.body.toString().slice(0, 200));
      assert.ok(a.body.equals(answers[0].body), `${path}: bytes differ between replicas`);
    }
  }
});

test('the lists follow uploads and deletions through other replicas within the poll', async () => {
  const [a, b, c] = topo.replicas;
  const made = await rename(a.url, 'listed by the others');
  assert.equal(made.status, 201);
  const { id } = await made.json();
  // Nothing asks b or c for this id: only their poll can list it.
  for (const r of [b, c]) {
    await eventually(`${r.url} lists ${id}`, async () => (await listed(r.url)).includes(id), (POLL_SECS + 5) * 1000);
  }
  const gone = await fetch(`${b.url}/api/v1/textures/${id}`, { method: 'DELETE', headers: { authorization: `Bearer ${TOKEN}` } });
  assert.equal(gone.status, 204);
  for (const r of [a, c]) {
    await eventually(`${r.url} forgets ${id}`, async () => !(await listed(r.url)).includes(id), (POLL_SECS + 5) * 1000);
    assert.equal((await get(r.url + tilePath(id, 0, 0, 0))).status, 404);
  }
});

test('identical uploads through several replicas agree on one texture, stored once', async (t) => {
  // One after the other, before any poll: the others find the object and store nothing.
  const [first, ...others] = topo.replicas;
  const made = await rename(first.url, 'the same upload twice');
  assert.equal(made.status, 201);
  const info = await made.json();
  for (const r of others) {
    const again = await rename(r.url, 'the same upload twice');
    assert.equal(again.status, 200, `${r.url} stored it again`);
    assert.deepEqual(await again.json(), info);
  }
  // At once: all answer the same texture. Garage ignores `If-None-Match: *`, so racing
  // uploads may each write (the same bytes) and each answer 201.
  const answers = await Promise.all(topo.replicas.map((r) => rename(r.url, 'the same upload everywhere')));
  const bodies = await Promise.all(answers.map((a) => a.json()));
  for (const a of answers) assert.ok([200, 201].includes(a.status), `status ${a.status}`);
  assert.ok(answers.some((a) => a.status === 201), 'none stored it');
  for (const b of bodies) assert.deepEqual(b, bodies[0]);
  t.diagnostic(`at once: ${answers.map((a) => a.status).join(', ')}`);
});

test('a replica restarted with an empty data directory serves from the bucket', async () => {
  const before = await listed(topo.replicas[0].url);
  const fresh = await topo.restart(2);
  assert.deepEqual(await listed(fresh.url), before);
  for (const id of [texture.id, before[before.length - 1]]) {
    const path = tilePath(id, 2, 1, 1, 'webp');
    const [mine, theirs] = await Promise.all([get(fresh.url + path), get(topo.replicas[0].url + path)]);
    assert.equal(mine.status, 200);
    assert.ok(mine.body.equals(theirs.body), `${path}: bytes differ from another replica's`);
  }
});

test('a replica restarting under load through nginx loses no request', async (t) => {
  const total = 900;
  const concurrency = 12;
  let next = 0;
  const failures = [];
  let restarted = null;
  async function worker() {
    while (next < total) {
      const i = next++;
      if (i === 200) restarted = topo.restart(1);
      const url = topo.url + tilePath(texture.id, 0, 300 + (i % 30), 250 + Math.floor(i / 30), 'jpg');
      try {
        const r = await get(url);
        if (r.status !== 200 || r.body.length === 0) failures.push(`${r.status} ${url}`);
      } catch (e) {
        failures.push(`${e.cause?.code || e.message} ${url}`);
      }
    }
  }
  await Promise.all(Array.from({ length: concurrency }, worker));
  await restarted;
  assert.deepEqual(failures, []);
  t.diagnostic(`${total} requests, replica 1 restarted (SIGTERM, then a new one on an empty data directory)`);
  assert.equal((await get(topo.replicas[1].url + tilePath(texture.id, 1, 2, 3))).status, 200);
});

/** Times one request. */
async function timed(url, init) {
  const t0 = performance.now();
  const r = await get(url, init);
  return { ...r, ms: performance.now() - t0 };
}

/** Checks a 503 is what an unavailable object store answers: JSON naming it, Retry-After. */
function assertUnavailable(r, what) {
  assert.equal(r.status, 503, `${what}: ${r.status} ${r.body.toString().slice(0, 200)}`);
  assert.equal(r.headers.get('retry-after'), '1', what);
  assert.equal(r.headers.get('content-type'), 'application/json', what);
  assert.match(JSON.parse(r.body).error, /object store/, what);
}

for (const [how, stop, restart] of [
  ['frozen (SIGSTOP: nothing answers)', (g) => g.pause(), (g) => g.resume()],
  ['stopped (its process gone)', (g) => g.kill(), (g) => g.start()],
]) {
  test(`the object store ${how}: 503s within the deadline, the textures held still served, then recovery without a restart`, async (t) => {
    const replica = topo.replicas[0];
    const unknown = 'a'.repeat(64);
    await stop(garage);
    try {
      const first = await timed(`${replica.url}/api/v1/textures/${unknown}`);
      assertUnavailable(first, 'an id this replica does not hold');
      assert.ok(first.ms < (TIMEOUT_SECS + 2) * 1000, `answered after ${first.ms.toFixed(0)} ms`);
      const upload = await timed(`${replica.url}/api/v1/textures/${texture.id}`, {
        method: 'PATCH',
        headers: { 'content-type': 'application/json', authorization: `Bearer ${TOKEN}` },
        body: JSON.stringify({ name: `made while the store is ${how}` }),
      });
      assertUnavailable(upload, 'an upload');
      assert.ok(upload.ms < (TIMEOUT_SECS + 2) * 1000, `upload answered after ${upload.ms.toFixed(0)} ms`);
      const deletion = await timed(`${replica.url}/api/v1/textures/${unknown}`, {
        method: 'DELETE',
        headers: { authorization: `Bearer ${TOKEN}` },
      });
      assertUnavailable(deletion, 'a deletion');
      // A texture the replica holds is still served, and the replica stays ready.
      const tile = await get(replica.url + tilePath(texture.id, 3, 4, 5));
      assert.equal(tile.status, 200);
      assert.equal((await get(`${replica.url}/readyz`)).status, 200);
      // Through nginx: the store's 503s reach the client and mark no replica failed, so tiles
      // the replicas hold (ones nginx has not cached) are still served, not 502.
      assertUnavailable(await get(`${topo.url}/api/v1/textures/${unknown}`), 'an unknown id through nginx');
      for (const [x, y] of [[2, 5], [3, 5], [4, 5]]) {
        const through = await get(topo.url + tilePath(texture.id, 3, x, y));
        assert.equal(through.status, 200, `a held texture's tile through nginx: ${through.status}`);
      }
      t.diagnostic(`503 after ${first.ms.toFixed(0)} ms (lookup), ${upload.ms.toFixed(0)} ms (upload), ${deletion.ms.toFixed(0)} ms (deletion)`);
    } finally {
      await restart(garage);
    }
    let made;
    await eventually('an upload succeeds again', async () => {
      made = await rename(replica.url, `made once the store was back (${how})`);
      return made.status === 201;
    }, 20_000);
    const { id } = await made.json();
    // Another replica that met the outage too (nginx sent it the unknown id) answers at once
    // only once its own pause after a failure is over.
    await eventually('another replica serves the new texture', async () => {
      return (await get(topo.replicas[1].url + tilePath(id, 4, 1, 1))).status === 200;
    }, 10_000);
    assert.match(replica.stderr(), /the object store failed/);
  });
}

test('a corrupt object is refused and reported, by the replicas polling and by one starting', async () => {
  const [a, b] = topo.replicas;
  const bundle = (await get(`${a.url}/api/v1/textures/${texture.id}/encoding`)).body;
  const damaged = Buffer.from(bundle);
  damaged[damaged.length >> 1] ^= 0xff;
  // Under a name nothing was stored as: every running replica's poll reads it and refuses it.
  const stranger = 'b'.repeat(64);
  garage.putObject(`${PREFIX}/${stranger}.vtex`, damaged);
  for (const r of topo.replicas) {
    await eventually(`${r.url} reports ${stranger}`, () => r.stderr().includes(`${stranger}.vtex`), (POLL_SECS + 5) * 1000);
    assert.match(r.stderr(), /not serving an invalid bundle of the store/);
  }
  for (const r of topo.replicas) {
    assert.ok(!(await listed(r.url)).includes(stranger));
    assert.equal((await get(r.url + tilePath(stranger, 0, 0, 0))).status, 404);
  }
  // Over a texture's own object: the replicas that checked their copies serve on, a replica
  // starting with no copy refuses it.
  garage.putObject(`${PREFIX}/${texture.id}.vtex`, damaged);
  const fresh = await topo.restart(2);
  assert.match(fresh.stderr(), new RegExp(`not serving an invalid bundle.*${texture.id}\\.vtex`));
  assert.ok(!(await listed(fresh.url)).includes(texture.id));
  const refused = await get(fresh.url + tilePath(texture.id, 0, 0, 0));
  assert.equal(refused.status, 404);
  assert.equal((await get(b.url + tilePath(texture.id, 0, 0, 0))).status, 200);
  garage.putObject(`${PREFIX}/${texture.id}.vtex`, bundle);
});
