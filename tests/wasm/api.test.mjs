// The WebAssembly modules as clients use them (client-web/src/shared/vtex-synth.js over
// wasm/src/api.rs), one per model, render exactly the native bytes: every demo through its
// model's module, its probe regions (levels 0 to the coarsest, far and negative coordinates, a
// later animation frame) and a few server tiles, against the native reference (`cargo run
// --bin reference`); a module refuses other models' bundles, naming the model it holds; and
// bad bundles and calls are errors that name the problem, never a trap.
// Needs: scripts/build-wasm
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { instantiate, SynthError } from '../../client-web/src/shared/vtex-synth.js';
import { MODELS, ROOT, modulePath } from './modules.mjs';

/** The reference's tile size (wasm/src/bin/reference.rs TILE_SIZE). */
const TILE_SIZE = 256;

let dir;
let reference;
/** model → an instance of that model's module. */
const synths = new Map();
/** The instance of the module of `demo`'s model. */
const synthOf = (demo) => synths.get(demo.info.model);

before(async () => {
  dir = mkdtempSync(join(tmpdir(), 'vtex-wasm-reference-'));
  execFileSync('cargo', ['run', '--quiet', '--release', '--locked', '-p', 'vtex-synth-wasm', '--bin', 'reference', '--', dir], {
    cwd: ROOT,
    stdio: ['ignore', 'inherit', 'inherit'],
  });
  reference = JSON.parse(readFileSync(join(dir, 'reference.json'), 'utf8'));
  for (const model of MODELS) synths.set(model, await instantiate(readFileSync(modulePath(model))));
});

after(() => rmSync(dir, { recursive: true, force: true }));

/** Index of the first differing byte of a and b, or -1. */
function firstDifference(a, b) {
  if (a.length !== b.length) return Math.min(a.length, b.length);
  for (let i = 0; i < a.length; i++) if (a[i] !== b[i]) return i;
  return -1;
}

const bundleOf = (demo) => readFileSync(join(dir, demo.bundle));

test('every demo renders its probe regions and tiles byte for byte like native', () => {
  const models = new Set();
  let compared = 0;
  for (const demo of reference.demos) {
    const tex = synthOf(demo).open(bundleOf(demo), TILE_SIZE);
    assert.deepEqual(tex.info, demo.info, `info of ${demo.info.name}`);
    models.add(tex.info.model);
    for (const c of demo.cases) {
      const what = `${demo.info.name} (${demo.info.model}) ${JSON.stringify({ ...c, rgba: undefined })}`;
      const run = () => (c.kind === 'region' ? tex.render(c) : tex.renderTile(c.level, c.tx, c.ty, c.frame));
      if (c.error) {
        assert.throws(run, (e) => e instanceof SynthError && e.message === c.error, what);
        continue;
      }
      const out = run();
      if (c.kind === 'tile') assert.deepEqual([out.width, out.height], [c.width, c.height], what);
      const at = firstDifference(c.kind === 'region' ? out : out.data, readFileSync(join(dir, c.rgba)));
      assert.equal(at, -1, `${what}: first difference at byte ${at} (pixel ${at >> 2})`);
      compared++;
    }
    tex.close();
  }
  assert.deepEqual([...models].sort(), ['cascade', 'chaos-mosaic', 'lcm', 'order-independent', 'patterns']);
  assert.deepEqual([...models].sort(), [...MODELS].sort(), 'a module for every model of the demos, and no other');
  assert.ok(compared >= reference.demos.length * 10, `only ${compared} regions and tiles compared`);
});

test('animated demos move: a tile differs at frames 0, 1, 10 and 37', () => {
  const animated = reference.demos.filter((d) => d.info.animated);
  assert.ok(animated.length > 0, 'no animated demo');
  for (const demo of animated) {
    const tex = synthOf(demo).open(bundleOf(demo), TILE_SIZE);
    const frames = [0, 1, 10, 37].map((frame) => Buffer.from(tex.renderTile(2, 0, 0, frame).data).toString('base64'));
    assert.equal(new Set(frames).size, 4, `${demo.info.name}: some of frames 0, 1, 10 and 37 are identical`);
    tex.close();
  }
});

test("a module refuses another model's bundle, naming the model it holds", () => {
  for (const [model, synth] of synths) {
    for (const demo of reference.demos.filter((d) => d.info.model !== model)) {
      assert.throws(
        () => synth.open(bundleOf(demo), TILE_SIZE),
        (e) => e instanceof SynthError && e.message === `model \`${demo.info.model}\` is not in this build, which holds only: ${model}`,
        `${model}'s module opening ${demo.info.name}`,
      );
    }
    assert.equal(synth.failure, null);
  }
});

test('bad bundles are errors that say what is wrong', () => {
  const synth = synthOf(reference.demos[0]);
  const rejects = (bytes, pattern) =>
    assert.throws(() => synth.open(bytes, TILE_SIZE), (e) => e instanceof SynthError && pattern.test(e.message), `expected ${pattern}`);
  const good = new Uint8Array(bundleOf(reference.demos[0]));
  const edited = (edit) => {
    const b = good.slice();
    edit(b);
    return b;
  };
  rejects(new Uint8Array(0), /truncated: magic/);
  rejects(new TextEncoder().encode('<!doctype html><title>404</title>'), /not a vtex bundle \(bad magic\)/);
  rejects(edited((b) => new DataView(b.buffer).setUint32(8, 2, true)), /container version 2; this build reads 1/);
  for (const cut of [9, 15, 100, good.length >> 1, good.length - 1]) rejects(good.slice(0, cut), /truncated/);
  rejects(new Uint8Array([...good, 0]), /1 unexpected bytes after the last section/);
  rejects(edited((b) => (b[16] = 0x5b)), /manifest/); // the manifest's JSON starts at byte 16
  const model = reference.demos[0].info.model;
  const text = Buffer.from(good).toString('latin1');
  const renamed = Buffer.from(text.replace(`"model":"${model}"`, `"model":"${'x'.repeat(model.length)}"`), 'latin1');
  rejects(new Uint8Array(renamed), /unknown model `x+`/);
});

test('flipped bytes all through a bundle give errors or textures, never a trap', () => {
  for (const demo of reference.demos.filter((d, i, all) => all.findIndex((e) => e.info.model === d.info.model) === i)) {
    const synth = synthOf(demo);
    const good = new Uint8Array(bundleOf(demo));
    const step = Math.max(1, Math.floor(good.length / 150));
    let refused = 0;
    for (let i = 0; i < good.length; i += step) {
      const bytes = good.slice();
      bytes[i] ^= 0x55;
      try {
        const tex = synth.open(bytes, TILE_SIZE);
        tex.renderTile(tex.info.levels - 1, 0, 0, 0);
        tex.close();
      } catch (e) {
        assert.ok(e instanceof SynthError, `${demo.info.name}, byte ${i}: ${e}`);
        assert.equal(synth.failure, null, `${demo.info.name}, byte ${i} trapped the module: ${e.message}`);
        refused++;
      }
    }
    assert.ok(refused > 0, `${demo.info.name}: no flipped byte was refused`);
  }
});

test('bad calls are errors and leave the module working', () => {
  const demo = reference.demos[0];
  const synth = synthOf(demo);
  const tex = synth.open(bundleOf(demo), TILE_SIZE);
  assert.throws(() => tex.render({ level: 99, x: 0, y: 0, width: 4, height: 4 }), /level 99 does not exist/);
  assert.throws(() => tex.render({ level: 0, x: 0.5, y: 0, width: 4, height: 4 }), /x = 0.5 is not an integer/);
  assert.throws(() => tex.render({ level: 0, x: 0, y: 0, width: 0, height: 4 }), /empty region/);
  assert.throws(() => tex.render({ level: 0, x: 0, y: 0, width: 8192, height: 8192 }), /at most 16777216 per render/);
  assert.throws(() => tex.renderTile(0, 1e6, 0), /outside level 0's/);
  assert.throws(() => tex.renderTile(tex.info.levels, 0, 0), /level \d+ does not exist/);
  assert.throws(() => synth.open(bundleOf(demo), 0), /invalid tile size 0: from 1 to 65535/);
  assert.throws(() => synth.open(bundleOf(demo), 65536), /invalid tile size 65536/);
  tex.close();
  assert.throws(() => tex.render({ level: 0, x: 0, y: 0, width: 4, height: 4 }), /is closed/);
  assert.equal(synth.exports.vtex_close(9999), 0);
  assert.equal(synth.outputText(), 'no open texture has handle 9999');
  const again = synth.open(bundleOf(demo), TILE_SIZE);
  const c = demo.cases.find((k) => k.rgba && k.kind === 'region');
  assert.equal(firstDifference(again.render(c), readFileSync(join(dir, c.rgba))), -1);
  again.close();
  assert.equal(synth.failure, null);
});
