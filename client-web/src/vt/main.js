// The virtual-texturing demo (vt.html): a camera flies over a virtual texture lying on the ground
// plane; each frame a feedback pass names the pages the visible fragments need, the missing ones
// (and their coarser ancestors) stream from vtex — a page alone, or the page metatile (an aligned
// block of pages) where most of one is wanted: immutable URLs that a cache in front shares
// between clients — into an atlas of bordered pages, and the colour pass samples the atlas
// through the page table.
//
// URL parameters: texture (id, name or id prefix; default the 100k chaos mosaic),
// camera=x,y,height,yaw,pitch (a fixed camera, drawn until every page it needs is resident;
// without it the camera flies, the same path at any frame rate), frames=N (draw N frames),
// format=rgba|bc7 (default bc7 where the GPU has BPTC), aniso=N (at most 4), slots=N (atlas
// slots a side, at least 5: the 21 pinned pages fit), feedback=N (the feedback buffer N times
// smaller than the view).
// debug (shared/debug.js): `window.vtDemo` exposes the state and a log of every page requested,
// made resident or evicted and every fetch, or the error that stopped the demo.

import { FrameReader, readChunks } from '../shared/batch.js';
import { MAX_ANISOTROPY, VtRenderer } from './gl.js';
import { parseKtx2, VK_FORMAT_BC7_SRGB } from './ktx2.js';
import { BORDER, PAGE_SIZE, PINNED_LEVELS, PageCache, decodeFeedback, fetchPlan, pageKey, plan, pyramid } from './pages.js';
import { findTexture } from '../shared/texture-lookup.js';
import { expose } from '../shared/debug.js';
import { fetchOk, getJson } from '../shared/http.js';

const FLAGSHIP = 'Pebbles — chaos mosaic 100k';
/** Pages in flight at once (so at most as many requests; the browser queues those past its connections). */
const PAGES_IN_FLIGHT = 64;
/** The fly-through: height above the ground and distance a frame, in level-0 texels. */
const FLIGHT = { height: 220, pitch: 20, step: 20, fov: 60 };

const params = new URLSearchParams(location.search);
const overlay = document.getElementById('overlay');
/** The message that stopped the demo, once it has stopped. */
let failure = null;

function fail(message) {
  failure = message;
  overlay.textContent = message;
  overlay.classList.add('error');
  expose('vtDemo', { error: message });
  throw new Error(message);
}

function number(name, fallback, min, max) {
  if (!params.has(name)) return fallback;
  const v = Number(params.get(name));
  if (!Number.isFinite(v) || v < min || v > max) fail(`?${name}= must be a number from ${min} to ${max}`);
  return v;
}

async function start() {
  const canvas = document.getElementById('view');
  const gl = canvas.getContext('webgl2', { antialias: false, preserveDrawingBuffer: true });
  if (!gl) fail('This browser has no WebGL2.');
  const list = await getJson('api/v1/textures', 'the texture list');
  const info = findTexture(list.textures, params.get('texture') || FLAGSHIP) || (!params.has('texture') && list.textures[0]);
  if (!info) fail(`no texture named ${params.get('texture')}`);

  const bptc = gl.getExtension('EXT_texture_compression_bptc');
  const format = params.get('format') || (bptc ? 'bc7' : 'rgba');
  if (format !== 'rgba' && format !== 'bc7') fail('?format= must be rgba or bc7');
  if (format === 'bc7' && !bptc) fail('this GPU has no BC7 (EXT_texture_compression_bptc): use ?format=rgba');
  const slotsPerSide = number('slots', 16, 5, Math.floor(gl.getParameter(gl.MAX_TEXTURE_SIZE) / (PAGE_SIZE + 2 * BORDER)));
  const frames = number('frames', Infinity, 1, 1e9);
  const pyr = pyramid(info);
  const renderer = new VtRenderer(gl, pyr, {
    slotsPerSide,
    bc7: format === 'bc7' ? bptc : null,
    feedbackScale: number('feedback', 8, 1, 32),
    anisotropy: number('aniso', MAX_ANISOTROPY, 1, MAX_ANISOTROPY),
  });
  const cache = new PageCache(slotsPerSide * slotsPerSide);

  let fixed = null;
  if (params.has('camera')) {
    const c = params.get('camera').split(',').map(Number);
    if (c.length !== 5 || c.some((v) => !Number.isFinite(v)) || c[2] <= 0) fail('?camera= must be x,y,height,yaw,pitch (height > 0)');
    fixed = { x: c[0], y: c[1], height: c[2], yaw: c[3], pitch: c[4], fov: FLIGHT.fov };
  }
  const camera = fixed || { x: info.width / 2, y: info.height / 2, height: FLIGHT.height, yaw: 0, pitch: FLIGHT.pitch, fov: FLIGHT.fov };

  const [ext, query] = format === 'bc7' ? ['ktx2', 'codec=bc7&'] : ['rgba', ''];
  const pageQuery = `${query}size=${PAGE_SIZE}&border=${BORDER}`;
  const state = {
    texture: info,
    format,
    anisotropy: renderer.anisotropy,
    frame: 0,
    inFlight: new Set(),
    /** Metatiles being fetched: key → the keys of the pages wanted from it. */
    fetching: new Map(),
    arrived: [],
    // { frame, event: 'request' | 'resident' | 'evict' | 'drop' | 'fetch', key }; a fetch's key is
    // 'page L/x/y' or 'metatile L/x/y'.
    log: [],
    // bytes: every page received; unused: those of pages a metatile brought that were not asked for.
    stats: { requested: 0, resident: 0, evicted: 0, bytes: 0, unused: 0, metatiles: 0, missing: 0 },
    frameMs: [], // from one frame's start to the next's
    cpuMs: [], // each frame's own work: feedback, read back, uploads, draw
    settled: false,
    done: false,
    error: null,
  };

  /**
   * Asks for `pages` (in priority order) as `fetchPlan` groups them; a page whose metatile is on
   * its way is taken from it as it arrives. Answers the fetches started.
   */
  function request(pages) {
    const started = [];
    for (const { metatile, pages: group } of fetchPlan(pages, (k) => state.fetching.has(k))) {
      const joining = metatile && state.fetching.get(metatile.key);
      for (const p of group) {
        state.inFlight.add(p.key);
        state.log.push({ frame: state.frame, event: 'request', key: p.key });
        state.stats.requested++;
        if (joining) joining.add(p.key);
      }
      if (joining) continue;
      if (metatile) {
        const { level, x, y, key } = metatile;
        const wanted = new Set(group.map((p) => p.key));
        state.fetching.set(key, wanted);
        state.stats.metatiles++;
        const url = `api/v1/textures/${info.id}/page-metatiles/${level}/${x}/${y}.${ext}?${pageQuery}`;
        started.push(fetchPages(`metatile ${key}`, url, wanted, readFrames).finally(() => state.fetching.delete(key)));
      } else {
        const { level, x, y, key } = group[0];
        const url = `api/v1/textures/${info.id}/pages/${level}/${x}/${y}.${ext}?${pageQuery}`;
        started.push(fetchPages(`page ${key}`, url, new Set([key]), async (r, take) => take(level, x, y, new Uint8Array(await r.arrayBuffer()))));
      }
    }
    return started;
  }

  /** A metatile's frames, each handed to `take` as it arrives. */
  async function readFrames(r, take) {
    const reader = new FrameReader((f) => {
      if (f.status !== 200) throw new Error(`page ${f.level}/${f.x}/${f.y}: status ${f.status}`);
      take(f.level, f.x, f.y, f.body);
    });
    await readChunks(r.body, (c) => reader.push(c));
  }

  /**
   * Fetches `url` (named `what` in the log), read by `read(response, take)`: each page `take`n
   * that is `wanted` arrives in `state.arrived`, the others are left.
   */
  async function fetchPages(what, url, wanted, read) {
    state.log.push({ frame: state.frame, event: 'fetch', key: what });
    const arrived = new Set();
    const take = (level, x, y, body) => {
      const key = pageKey(level, x, y);
      state.stats.bytes += body.length;
      if (!wanted.has(key)) {
        state.stats.unused += body.length;
        return;
      }
      arrived.add(key);
      state.arrived.push({ key, level, x, y, body: body.slice() });
    };
    try {
      await read(await fetchOk(url), take);
    } catch (e) {
      state.error = String(e);
      overlay.classList.add('error');
    } finally {
      // Pages this fetch failed to bring are no longer in flight (and may be asked again).
      for (const key of wanted) {
        if (!arrived.has(key) && state.inFlight.delete(key)) state.log.push({ frame: state.frame, event: 'drop', key });
      }
    }
  }

  /** Puts arrived pages into the atlas and the page table, evicting least recently used ones. */
  function makeResident(pinned) {
    for (const page of state.arrived.splice(0)) {
      state.inFlight.delete(page.key);
      const placed = cache.insert(page, state.frame, pinned);
      if (!placed) {
        state.log.push({ frame: state.frame, event: 'drop', key: page.key });
        continue;
      }
      if (placed.evicted) {
        const e = placed.evicted;
        renderer.map(e.level, e.x, e.y, null);
        state.stats.evicted++;
        state.log.push({ frame: state.frame, event: 'evict', key: e.key });
      }
      const body = format === 'bc7' ? blocks(page.body) : page.body;
      renderer.upload(placed.slot, body);
      renderer.map(page.level, page.x, page.y, placed.slot);
      state.stats.resident++;
      state.log.push({ frame: state.frame, event: 'resident', key: page.key });
    }
  }

  // The coarsest levels first, pinned: a fragment whose page is not resident falls back to them.
  const pinned = [];
  for (let l = Math.max(0, pyr.maxLevel - PINNED_LEVELS + 1); l <= pyr.maxLevel; l++) {
    const [cols, rows] = pyr.grid(l);
    for (let y = 0; y < rows; y++) for (let x = 0; x < cols; x++) pinned.push({ key: pageKey(l, x, y), level: l, x, y });
  }
  await Promise.all(request(pinned));
  if (state.error) fail(state.error);
  makeResident(true);

  let last = performance.now();
  let idleFrames = 0;
  function step(now) {
    const t0 = performance.now();
    state.frameMs.push(now - last);
    last = now;
    if (!fixed) fly(camera, state.frame);
    const width = canvas.width;
    const height = canvas.height;
    const needed = decodeFeedback(renderer.feedback(camera, width, height));
    state.frame++;
    const missing = cache.use(needed, state.frame, pyr.maxLevel);
    makeResident(false);
    state.stats.missing = missing;
    // No more in flight than the atlas could take now: a page that finds no slot is dropped.
    const room = Math.min(PAGES_IN_FLIGHT, cache.available(state.frame));
    const queue = plan(needed, (k) => cache.has(k), (k) => state.inFlight.has(k), pyr.maxLevel);
    request(queue.slice(0, Math.max(0, room - state.inFlight.size)));
    renderer.draw(camera, width, height);
    state.needed = needed.size;
    state.cpuMs.push(performance.now() - t0);
    showOverlay(state.cpuMs.at(-1));
    idleFrames = missing === 0 && state.inFlight.size === 0 && state.arrived.length === 0 ? idleFrames + 1 : 0;
    // A fixed camera stops drawing once every page it needs is resident and drawn (unless a
    // number of frames is asked for).
    state.settled = fixed !== null && idleFrames >= 2 && frames === Infinity;
    if (state.frame >= frames) state.done = true;
    if (!state.settled && !state.done) requestAnimationFrame(step);
  }

  function showOverlay(cpuMs) {
    const recent = state.frameMs.slice(-30);
    const mean = recent.reduce((a, b) => a + b, 0) / recent.length;
    overlay.textContent = [
      `${info.name} · ${format.toUpperCase()} pages ${PAGE_SIZE}² + ${BORDER} px border · aniso ${renderer.anisotropy}×`,
      `resident ${cache.size}/${cache.slots.length} · needed ${state.needed} (missing ${state.stats.missing})`,
      `requested ${state.stats.requested} in ${state.stats.metatiles} metatiles · in flight ${state.inFlight.size} · evicted ${state.stats.evicted} · ${(state.stats.bytes / 1e6).toFixed(1)} MB (${(state.stats.unused / 1e6).toFixed(1)} not asked for)`,
      `frame ${mean.toFixed(1)} ms (${(1000 / mean).toFixed(0)} fps) · CPU ${cpuMs.toFixed(1)} ms · frame #${state.frame}`,
      state.error ? `error: ${state.error}` : '',
    ].join('\n');
  }

  function resize() {
    canvas.width = Math.max(1, Math.round(canvas.clientWidth));
    canvas.height = Math.max(1, Math.round(canvas.clientHeight));
    if (state.settled) {
      state.settled = false;
      idleFrames = 0;
      requestAnimationFrame(step);
    }
  }
  window.addEventListener('resize', resize);
  resize();

  expose('vtDemo', { state, cache, pyramid: pyr, camera, resident: (key) => cache.has(key) });
  requestAnimationFrame(step);
}

/** BC7 blocks of a KTX2 page. */
function blocks(ktx2) {
  const k = parseKtx2(ktx2);
  if (k.vkFormat !== VK_FORMAT_BC7_SRGB) throw new Error(`page is vkFormat ${k.vkFormat}, not BC7 sRGB`);
  return k.data(0);
}

/** The fly-through at `frame`: forward a constant step a frame, turning slowly from side to side. */
function fly(camera, frame) {
  camera.yaw = 35 * Math.sin(frame / 540);
  const yaw = (camera.yaw * Math.PI) / 180;
  camera.x += Math.sin(yaw) * FLIGHT.step;
  camera.y -= Math.cos(yaw) * FLIGHT.step;
}

start().catch((e) => {
  if (failure === null) fail(String(e));
});
