// The vtex viewer: OpenSeadragon deep zoom over the vtex tile API, with a navigator, a texture
// picker, an info panel, live tile statistics, the view in the URL and animation playback.

import { createTileSource } from './tilesource.js';
import { TileStats, formatBytes, formatRatio } from './stats.js';
import { FORMATS, parseView, formatView } from './view-url.js';
import { DEFAULT_DETAIL, DETAIL, drawLevel, modulo, vtexLevel } from './pyramid.js';
import { updateEarly } from './loader.js';
import { findTexture as lookupTexture } from '../shared/texture-lookup.js';
import { firstView, openingView } from './first-view.js';
import { fetchWantedLevels, keepBatchesOnDraw, vtexDrawer } from './osd-adapter.js';
import { ClientSynth, staticExport } from './client-synth.js';
import { setupCreatePanel } from './create-panel.js';
import { expose, keepDebug } from '../shared/debug.js';
import { getJson } from '../shared/http.js';

const OSD = window.OpenSeadragon;
const $ = (id) => document.getElementById(id);
const num = (n) => Number(n).toLocaleString('en-US');

const stats = new TileStats();
// On this machine bandwidth is free and decoding is the cost: raw RGBA. Over a network, PNG.
const LOOPBACK = ['127.0.0.1', 'localhost', '[::1]'].includes(location.hostname);
const DEFAULT_FORMAT = LOOPBACK ? 'rgba' : 'png';
const state = {
  textures: [],
  info: null,
  /** Counts texture opens, so a slow open superseded by a newer one is ignored. */
  openSeq: 0,
  /** The open in progress: its tile source and the view to apply once it is open. */
  opening: null,
  /** The animation frame on screen, and the tiled image showing it. */
  frame: 0,
  item: null,
  /** Tile format requested (png, webp, jpg, rgba). */
  format: DEFAULT_FORMAT,
  /** How fine a level is drawn (pyramid.js DETAIL). */
  detail: DEFAULT_DETAIL,
  /** Where tiles are made: 'server', or 'client' (in this page from the encoding; client-synth.js). */
  synthMode: 'server',
  /** The ClientSynth of the open texture in client mode. */
  synth: null,
  /** A static export's description (no server: client mode only), else null. */
  exported: null,
  /** A frame being loaded behind the visible one (invisible until fully loaded). */
  pending: null,
  playing: false,
  playTimer: 0,
  frameTimes: [],
};

// A tile's ImageBitmap is freed when OpenSeadragon drops it from its cache, not at the next
// garbage collection.
OSD.converter.learnDestroy('imageBitmap', (bitmap) => bitmap.close());

const viewer = OSD({
  element: $('osd'),
  prefixUrl: 'osd/images/',
  // The 2D canvas drawer (exact pixels at 1:1, no dependence on a GPU), also for the navigator.
  drawer: vtexDrawer(OSD),
  showNavigator: true,
  navigatorPosition: 'BOTTOM_RIGHT',
  navigatorAutoFade: false,
  navigatorOpacity: 1, // opaque: the view behind must not show through the minimap
  navigatorDisplayRegionColor: '#f22',
  navigatorBorderColor: '#888',
  navigatorSizeRatio: 0.18,
  showRotationControl: false,
  autoHideControls: false,
  // Deep zoom down past 1:1 so single texels can be inspected; out to the whole texture.
  maxZoomPixelRatio: 16,
  // Tiles drawn straight onto the canvas at every zoom: composing them on a sketch canvas first
  // (OSD's default past 1.1 × image zoom) moves magnified texels by a fraction of a pixel.
  // Seams between smoothed tiles are hidden by the drawer's one-pixel overlap instead.
  smoothTileEdgesMinZoom: Infinity,
  minZoomImageRatio: 0.5,
  visibilityRatio: 0.25,
  animationTime: 0.5,
  blendTime: 0,
  // The level drawn: pyramid.js DETAIL, set per texture opened (openTexture).
  minPixelRatio: DETAIL[DEFAULT_DETAIL],
  immediateRender: false, // coarsest first: a preview (osd-adapter.js fetchWantedLevels), then the finest level
  // Ask for every tile the view needs in its first frame (OSD's default of one a frame makes
  // a view crawl in), all at once: the tile source sends the jobs of one update as one
  // batched request (tilesource.js), so the loader sets no limit (0) — a limit would split a
  // view into several requests.
  maxTilesPerFrame: 64,
  imageLoaderLimit: 0,
  maxImageCacheCount: 400,
  timeout: 30000,
  gestureSettingsMouse: { clickToZoom: false, dblClickToZoom: true, scrollToZoom: true, dragToPan: true },
  gestureSettingsTouch: { pinchToZoom: true, dblClickToZoom: true, flickEnabled: true },
  crossOriginPolicy: false,
});
keepBatchesOnDraw(viewer);
fetchWantedLevels(viewer);
updateEarly(viewer);

// ---------------------------------------------------------------------------------------
// Texture list, picker and opening

function showError(message) {
  const box = $('error');
  box.textContent = message;
  box.hidden = !message;
}

function fillPicker(textures, selectedId) {
  const picker = $('texture-picker');
  picker.replaceChildren(
    ...textures.map((t) => {
      const option = document.createElement('option');
      option.value = t.id;
      option.textContent = `${t.name} — ${t.model}, ${num(t.width)} × ${num(t.height)}${t.animated ? ', animated' : ''}`;
      option.selected = t.id === selectedId;
      return option;
    }),
  );
  picker.disabled = textures.length === 0;
}

function findTexture(key) {
  return lookupTexture(state.textures, key);
}

/** The zoom at which `info` fits the view whole, as OpenSeadragon's home shows it. */
function fitZoom(info) {
  const size = viewer.viewport.getContainerSize();
  return Math.min(size.x / info.width, size.y / info.height);
}

/** Opens `info`; `view` (zoom, x, y, frame) is applied once it is open, else the whole texture shows. */
function openTexture(info, view = {}) {
  const seq = ++state.openSeq;
  stopPlayback();
  state.info = info;
  state.pending = null;
  state.frame = info.animated ? normaliseFrame(view.frame || 0) : 0;
  document.title = `${info.name} – vtex viewer`;
  renderInfo(info);
  setupAnimationPanel(info);
  if (view.format) state.format = view.format;
  $('format').value = state.format;
  if (view.detail) state.detail = view.detail;
  $('detail').value = state.detail;
  viewer.minPixelRatio = DETAIL[state.detail]; // read by every tiled image added from now on
  // A torus repeats past its edges (its tiles wrap: pyramid.js sourceTile), so pans are unbounded.
  viewer.wrapHorizontal = viewer.wrapVertical = info.wraps; // read by every tiled image too
  viewer.viewport.wrapHorizontal = viewer.viewport.wrapVertical = info.wraps;
  if (view.synth) state.synthMode = view.synth;
  $('synth').value = state.synthMode;
  $('format').disabled = state.synthMode === 'client';
  const source = createTileSource(OSD, info, { frame: state.frame, format: state.format, stats, synth: synthFor(info) });
  state.opening = { source, view, seq };
  state.item = null;
  viewer.open(source);
}

/** The ClientSynth of `info` in client mode (one per open texture, every frame's), else null. */
function synthFor(info) {
  if (state.synth && (state.synthMode !== 'client' || state.synth.info.id !== info.id)) {
    state.synth.close();
    state.synth = null;
  }
  if (state.synthMode !== 'client' || state.synth) return state.synth;
  const synth = new ClientSynth(info, { stats, encodingUrl: state.exported?.encodings[info.id] });
  synth.ready.catch((e) => state.synth === synth && showError(e.message));
  state.synth = synth;
  return synth;
}

// Only the most recent open counts: a texture picked while another was still opening wins.
viewer.addHandler('open', (e) => {
  const opening = state.opening;
  if (!opening || e.source !== opening.source || opening.seq !== state.openSeq) return;
  state.opening = null;
  state.item = viewer.world.getItemAt(0);
  const view = opening.view;
  if (view.zoom > 0 && Number.isFinite(view.x) && Number.isFinite(view.y)) setView(view, true);
  bringBackTorusView();
  updateSmoothing();
  updateUrl();
  updateReadouts();
});

// ---------------------------------------------------------------------------------------
// The view in level-0 pixels

/** The current view: centre in level-0 pixels and zoom in screen pixels per level-0 pixel. */
function getView() {
  const item = state.item;
  if (!item || !state.info) return null;
  const centre = item.viewportToImageCoordinates(viewer.viewport.getCenter(true));
  return {
    texture: state.info.id,
    zoom: item.viewportToImageZoom(viewer.viewport.getZoom(true)),
    x: centre.x,
    y: centre.y,
    frame: state.frame,
    format: state.format === DEFAULT_FORMAT ? undefined : state.format,
    detail: state.detail === DEFAULT_DETAIL ? undefined : state.detail,
    synth: state.synthMode === 'client' && !state.exported ? 'client' : undefined,
  };
}

/** Moves to `view` (any of zoom, x, y), immediately or animated. */
function setView(view, immediately = false) {
  const item = state.item;
  if (!item) return;
  if (view.zoom > 0) viewer.viewport.zoomTo(item.imageToViewportZoom(view.zoom), null, immediately);
  if (Number.isFinite(view.x) && Number.isFinite(view.y)) {
    viewer.viewport.panTo(item.imageToViewportCoordinates(view.x, view.y), immediately);
  }
}

let urlTimer = 0;
function updateUrl() {
  clearTimeout(urlTimer);
  urlTimer = setTimeout(() => {
    const view = getView();
    if (view) history.replaceState(null, '', keepDebug(formatView(view)));
  }, 150);
}

/** vtex level of the finest tiles drawn in the last frame (what the screen shows). */
function drawnLevels() {
  const item = state.item;
  if (!item || !state.info) return [];
  const levels = new Set();
  for (const t of item.getTilesToDraw()) if (t.tile.loaded) levels.add(vtexLevel(state.info, t.tile.level));
  return [...levels].sort((a, b) => a - b);
}

// ---------------------------------------------------------------------------------------
// Panels

function renderInfo(info) {
  const rows = [
    ['Name', info.name],
    ['Model', info.model],
    ['Size', `${num(info.width)} × ${num(info.height)} px`],
    ['Levels', `${info.levels} (0 = full res.)`],
    ['Tile size', `${info.tile_size} px`],
    ['Domain', `${info.domain}${info.wraps ? ', wraps' : ''}`],
    ['Encoding', `${formatBytes(info.encoding_bytes)} (${num(info.encoding_bytes)} B)`],
    ['Explicit (24-bit)', `${formatBytes(info.explicit_bytes)}`],
    ['Explicit : encoding', formatRatio(info.explicit_bytes, info.encoding_bytes)],
    ['Id', info.id.slice(0, 16) + '…'],
  ];
  if (info.animated && info.animation) {
    rows.splice(6, 0, ['Animation', `${info.animation.fps} fps, ${info.animation.period_frames ? `period ${info.animation.period_frames} frames` : 'aperiodic'}`]);
  }
  fillDl($('info'), rows);
  $('info').lastElementChild.title = info.id;
}

function fillDl(dl, rows) {
  dl.replaceChildren(
    ...rows.flatMap(([k, v]) => {
      const dt = document.createElement('dt');
      dt.textContent = k;
      const dd = document.createElement('dd');
      dd.textContent = v;
      return [dt, dd];
    }),
  );
}

function renderStats() {
  const s = stats.snapshot();
  const ms = (v) => (Number.isFinite(v) ? `${v.toFixed(1)} ms` : '–');
  const served = s.serverHits + s.serverMisses;
  const rows = [
    ['Requested', `${num(s.requested)} tiles in ${num(s.batches)} requests`],
    ['Loaded', num(s.loaded)],
    ['Transferred', formatBytes(s.wireBytes)],
    ['Tile bodies', formatBytes(s.bodyBytes)],
    ['Server cache hits', served ? `${num(s.serverHits)} / ${num(served)} (${((100 * s.serverHits) / served).toFixed(0)}%)` : '–'],
    ['Browser cache', num(s.browserCached)],
    ['Latency p50', ms(s.p50)],
    ['Latency p95', ms(s.p95)],
  ];
  if (s.aborted) rows.push(['Cancelled', num(s.aborted)]);
  if (s.failed) rows.push(['Failed', `${num(s.failed)}: ${s.lastError}`]);
  fillDl($('stats'), rows);
}

/**
 * Sets an element's text only when it changes: this runs after every frame, and a changed
 * text makes the next frame lay the page out again (OpenSeadragon reads its container's size).
 */
function setText(element, text) {
  if (element.textContent !== text) element.textContent = text;
}

let pointer = null;
function updateReadouts() {
  const item = state.item;
  const info = state.info;
  if (!item || !info) return;
  const zoom = item.viewportToImageZoom(viewer.viewport.getZoom(true));
  const levels = drawnLevels();
  const shown = levels.length ? `level ${levels[0]}` : 'loading';
  setText($('zoom-readout'), `zoom ${zoom >= 1 ? zoom.toFixed(2) : `1/${(1 / zoom).toFixed(1)}`} · ${shown}`);
  if (pointer) {
    const p = item.viewerElementToImageCoordinates(new OSD.Point(pointer.x, pointer.y));
    const wrap = (v, n) => (info.wraps ? modulo(v, n) : v);
    const x = wrap(Math.floor(p.x), info.width);
    const y = wrap(Math.floor(p.y), info.height);
    $('coords').textContent = x >= 0 && y >= 0 && x < info.width && y < info.height ? `x ${num(x)}, y ${num(y)}` : 'outside';
  }
}

$('osd').addEventListener('pointermove', (e) => {
  const r = viewer.element.getBoundingClientRect();
  pointer = { x: e.clientX - r.left, y: e.clientY - r.top };
  updateReadouts();
});
$('osd').addEventListener('pointerleave', () => {
  pointer = null;
  $('coords').textContent = '–';
});

// ---------------------------------------------------------------------------------------
// Animation: each frame is its own tiled image, loaded invisibly behind the one on screen and
// swapped in once complete, so playback never shows a half-drawn frame.

function normaliseFrame(f) {
  const period = state.info && state.info.animation ? state.info.animation.period_frames : 0;
  f = Math.max(0, Math.floor(f));
  return period > 0 ? f % period : f;
}

function setupAnimationPanel(info) {
  const panel = $('animation');
  panel.hidden = !info.animated;
  if (!info.animated) return;
  const period = info.animation ? info.animation.period_frames : 0;
  const slider = $('frame-slider');
  slider.max = String(period > 0 ? period - 1 : 999);
  slider.value = String(state.frame);
  $('frame-readout').textContent = `frame ${state.frame}`;
  $('fps-readout').textContent = '';
}

function showFrame(frame) {
  const info = state.info;
  if (!info || !info.animated || !state.item) return;
  frame = normaliseFrame(frame);
  if (frame === state.frame && !state.pending) return;
  if (state.pending) {
    viewer.world.removeItem(state.pending.item);
    state.pending = null;
  }
  const seq = state.openSeq;
  viewer.addTiledImage({
    tileSource: createTileSource(OSD, info, { frame, format: state.format, stats, synth: state.synth }),
    opacity: 0,
    preload: true,
    success: ({ item }) => {
      if (seq !== state.openSeq) return;
      const pending = { item, frame };
      state.pending = pending;
      const swap = () => {
        if (state.pending !== pending) return;
        item.setOpacity(1);
        const old = state.item;
        state.item = item;
        state.pending = null;
        state.frame = frame;
        if (old) viewer.world.removeItem(old);
        frameShown(frame);
      };
      if (item.getFullyLoaded()) swap();
      else item.addHandler('fully-loaded-change', (e) => e.fullyLoaded && swap());
    },
  });
}

function frameShown(frame) {
  $('frame-readout').textContent = `frame ${frame}`;
  $('frame-slider').value = String(frame);
  updateUrl();
  if (!state.playing) return;
  const now = performance.now();
  state.frameTimes.push(now);
  while (state.frameTimes.length > 20) state.frameTimes.shift();
  if (state.frameTimes.length > 1) {
    const span = (now - state.frameTimes[0]) / 1000;
    $('fps-readout').textContent = `playing at ${((state.frameTimes.length - 1) / span).toFixed(1)} fps (target ${state.info.animation.fps})`;
  }
  const interval = 1000 / Math.max(0.1, state.info.animation.fps);
  const last = state.frameTimes.length > 1 ? state.frameTimes[state.frameTimes.length - 2] : now - interval;
  clearTimeout(state.playTimer);
  state.playTimer = setTimeout(() => state.playing && showFrame(state.frame + 1), Math.max(0, last + interval - now));
}

function startPlayback() {
  if (!state.info || !state.info.animated || state.playing) return;
  state.playing = true;
  state.frameTimes = [];
  $('play').textContent = 'Pause';
  showFrame(state.frame + 1);
}

function stopPlayback() {
  state.playing = false;
  clearTimeout(state.playTimer);
  $('play').textContent = 'Play';
}

$('play').addEventListener('click', () => (state.playing ? stopPlayback() : startPlayback()));
$('step-back').addEventListener('click', () => {
  stopPlayback();
  const period = state.info.animation ? state.info.animation.period_frames : 0;
  showFrame(state.frame > 0 ? state.frame - 1 : period > 0 ? period - 1 : 0);
});
$('step-fwd').addEventListener('click', () => {
  stopPlayback();
  showFrame(state.frame + 1);
});
$('frame-slider').addEventListener('input', (e) => {
  stopPlayback();
  showFrame(Number(e.target.value));
});

// ---------------------------------------------------------------------------------------
// Wiring

viewer.addHandler('animation-finish', () => {
  bringBackTorusView();
  updateUrl();
});
// A torus view panned past the edges is moved back by whole periods, to the same pixels, so
// the navigator's box and the link's coordinates stay on the texture.
function bringBackTorusView() {
  const view = getView();
  if (!view || !state.info.wraps) return;
  const x = modulo(view.x, state.info.width);
  const y = modulo(view.y, state.info.height);
  if (x !== view.x || y !== view.y) setView({ x, y }, true);
}
// After the frame's OpenSeadragon work, not inside it: the navigator reads the viewer's size
// right after this event, and a readout changed before that read makes it lay the page out
// there and then, a second layout in the frame.
viewer.addHandler('update-viewport', () => queueMicrotask(updateReadouts));
// Smooth unless tile pixels land on screen pixels one to one, or level-0 pixels are magnified:
// past 1:1 at level 0 texels show as crisp squares, for inspection; a coarser level magnified
// (up to 1.41 × with the `map` detail) is filtered, as a GPU filters a magnified mip level.
function updateSmoothing() {
  if (!state.item || !state.info) return;
  const zoom = state.item.viewportToImageZoom(viewer.viewport.getZoom(true));
  const level = drawLevel(state.info, zoom, DETAIL[state.detail]);
  const ratio = zoom * 2 ** level;
  viewer.drawer.setImageSmoothingEnabled(Math.abs(ratio - 1) > 0.001 && !(level === 0 && ratio > 1));
}
viewer.addHandler('zoom', updateSmoothing);
viewer.addHandler('open-failed', (e) => showError(`Could not open the texture: ${e.message}`));

$('format').addEventListener('change', (e) => {
  if (!FORMATS.includes(e.target.value) || !state.info) return;
  const view = getView() || {};
  openTexture(state.info, { ...view, format: e.target.value });
});

$('detail').addEventListener('change', (e) => {
  if (!Object.hasOwn(DETAIL, e.target.value) || !state.info) return;
  const view = getView() || {};
  openTexture(state.info, { ...view, detail: e.target.value });
});

$('synth').addEventListener('change', (e) => {
  if (!['server', 'client'].includes(e.target.value) || !state.info) return;
  showError('');
  openTexture(state.info, { ...(getView() || {}), synth: e.target.value });
});

$('texture-picker').addEventListener('change', (e) => {
  const info = findTexture(e.target.value);
  if (info) openTexture(info, openingView(info, {}, fitZoom(info)));
});

$('copy-link').addEventListener('click', async () => {
  const view = getView();
  if (!view) return;
  const link = new URL(formatView(view), location.href).href;
  history.replaceState(null, '', keepDebug(formatView(view)));
  try {
    await navigator.clipboard.writeText(link);
    $('copy-link').textContent = 'Copied';
  } catch {
    $('copy-link').textContent = 'Link in address bar';
  }
  setTimeout(() => ($('copy-link').textContent = 'Copy link'), 1500);
});

$('reset-stats').addEventListener('click', () => {
  stats.reset();
  renderStats();
});

setInterval(renderStats, 250);

// Hooks for the end-to-end tests (tests/browser/) and the viewer bench (bench/viewer/), on a
// page opened with `?debug` (shared/debug.js).
expose('vtexViewer', { viewer, stats, state, getView, setView, drawnLevels, openTexture, findTexture, showFrame });

/** Lists the textures again and opens `info`, one just created (create-panel.js). */
async function openCreated(info) {
  state.textures = (await getJson('api/v1/textures')).textures;
  const listed = findTexture(info.id) || info;
  fillPicker(state.textures, listed.id);
  showError('');
  openTexture(listed, openingView(listed, {}, fitZoom(listed)));
}

async function start() {
  renderStats();
  const view = parseView(location.search);
  try {
    state.exported = await staticExport();
    state.textures = state.exported ? state.exported.textures : (await getJson('api/v1/textures')).textures;
  } catch (e) {
    showError(`Could not list textures: ${e.message}`);
    return;
  }
  if (state.exported) {
    state.synthMode = 'client';
    $('synth').disabled = true;
    $('create-toggle').hidden = true; // a static export has no server to create on
  } else {
    setupCreatePanel({ onCreated: openCreated });
  }
  if (state.textures.length === 0) {
    showError('The server has no textures yet: create one (Create a texture…) or upload one with POST /api/v1/textures.');
    return;
  }
  const { info, view: opened, message } = firstView(state.textures, view, fitZoom);
  showError(message);
  fillPicker(state.textures, info.id);
  openTexture(info, opened);
  $('osd').querySelector('.openseadragon-canvas')?.focus();
}

start();
