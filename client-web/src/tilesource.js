// An OpenSeadragon tile source over the vtex tile API. Tiles are loaded in batches, one
// request for all the tiles a view needs (batch.js; a browser spends ~3 ms of CPU on every
// request, BENCHMARKS.md "Viewer"), and each tile reports what the server says about it
// (cache hit or miss) and how long it took. Formats: png / webp (lossless), jpg (lossy,
// smallest) and rgba (raw: no decoding, the fastest on a fast link).

import { inPyramid, tileUrl, vtexLevel } from './pyramid.js';
import { FrameReader, MAX_BATCH, batchUrl, tileKey } from './batch.js';

/**
 * Makes the tile source for texture `info` (the server's info JSON) at animation `frame`.
 * `stats` is a TileStats that every download reports to.
 */
export function createTileSource(OSD, info, { frame = 0, format = 'png', stats }) {
  const maxLevel = info.levels - 1;
  const inFlight = new Set();
  let pending = [];
  const flush = () => {
    const jobs = pending;
    pending = [];
    const live = jobs.filter((job) => !job.userData.done);
    for (let i = 0; i < live.length; i += MAX_BATCH) {
      loadBatch(info, live.slice(i, i + MAX_BATCH), { frame, format, stats });
    }
  };
  const source = new OSD.TileSource({
    width: info.width,
    height: info.height,
    tileSize: info.tile_size,
    tileOverlap: 0,
    minLevel: 0,
    maxLevel,
    vtexInfo: info,
    vtexFrame: frame,
    vtexFormat: format,

    getTileUrl(level, x, y) {
      // OSD only asks for tiles that tileExists() accepted; null would be a bug upstream.
      return tileUrl(info, vtexLevel(info, level), x, y, frame, format);
    },

    tileExists(level, x, y) {
      return inPyramid(info, vtexLevel(info, level), x, y);
    },

    // Tiles are opaque: OSD may then skip drawing coarser levels under a complete finer one.
    hasTransparency() {
      return false;
    },

    // The jobs OpenSeadragon starts in one task (one update: every tile a view needs) go out
    // as one batched request, flushed in a microtask; each job finishes as its frame arrives.
    downloadTileStart(job) {
      const data = job.userData;
      data.done = false;
      data.t0 = performance.now();
      // Finishing twice (a frame after OSD's own timeout) would unbalance OSD's job count.
      const finish = job.finish.bind(job);
      job.finish = (result, request, error) => {
        if (data.finished) return;
        data.finished = true;
        data.done = true;
        inFlight.delete(job);
        finish(result, request, error);
      };
      inFlight.add(job);
      stats.started();
      pending.push(job);
      if (pending.length === 1) queueMicrotask(flush);
    },

    // The tile is no longer wanted (loader.js): its frame is ignored, and the request is
    // aborted (the server stops making its tiles) once none of its tiles is wanted.
    downloadTileAbort(job) {
      if (!inFlight.delete(job)) return; // never started (OSD's queue), or already finished
      const data = job.userData;
      data.done = true;
      stats.abortedTile();
      const batch = data.batch;
      if (batch && !data.settled && --batch.live === 0) batch.controller.abort();
    },

    // A tile arrives as the 2D context the canvas drawer draws from (see tileContext below), so
    // nothing is converted while a frame is drawn.
    createTileCache(cache, context) {
      cache._data = context;
    },

    destroyTileCache(cache) {
      if (cache._data) releaseContext(cache._data);
      cache._data = null;
    },

    getTileCacheData(cache) {
      return cache._data;
    },

    getTileCacheDataAsImage(cache) {
      return cache._data && cache._data.canvas;
    },

    getTileCacheDataAsContext2D(cache) {
      return cache._data;
    },
  });
  // Jobs started and neither finished nor aborted (loader.js drops those a view left).
  source.vtexInFlight = inFlight;
  return source;
}

/**
 * A canvas of w × h and its 2D context: a tile's pixels, ready for the drawer. Filled when the
 * tile arrives (in the fetch's task, between frames) rather than on first draw (inside a frame).
 */
function tileContext(w, h) {
  const canvas = document.createElement('canvas');
  canvas.width = w;
  canvas.height = h;
  return canvas.getContext('2d');
}

/** Frees a tile's pixels now rather than at the next garbage collection. */
function releaseContext(context) {
  context.canvas.width = 0;
  context.canvas.height = 0;
}

/**
 * Fetches the tiles of `jobs` in one request and finishes each job as its frame arrives (in the
 * server's completion order). Jobs aborted meanwhile are skipped; a batch with none left is
 * aborted. A tile the response does not carry (error, cut-off stream) fails its job.
 */
function loadBatch(info, jobs, { frame, format, stats }) {
  const controller = new AbortController();
  // Jobs by tile: the navigator shows this tile source too, so two jobs may want one tile.
  const byKey = new Map();
  const batch = { controller, live: jobs.length };
  const tiles = [];
  for (const job of jobs) {
    const t = { level: vtexLevel(info, job.tile.level), x: job.tile.x, y: job.tile.y };
    const key = tileKey(t.level, t.x, t.y);
    if (byKey.has(key)) byKey.get(key).push(job);
    else {
      byKey.set(key, [job]);
      tiles.push(t);
    }
  }
  const url = batchUrl(info, tiles, frame, format);
  const sent = performance.now();
  for (const job of jobs) {
    job.userData.batch = batch;
    job.userData.batchUrl = url;
    job.userData.sent = sent;
  }
  stats.batchStarted();
  // A job is settled once its frame came (or the batch failed): it no longer counts as live.
  const settle = (job) => {
    if (job.userData.settled) return;
    job.userData.settled = true;
    const key = tileKey(vtexLevel(info, job.tile.level), job.tile.x, job.tile.y);
    const left = (byKey.get(key) || []).filter((j) => j !== job);
    if (left.length) byKey.set(key, left);
    else byKey.delete(key);
    if (!job.userData.done) batch.live--;
  };
  const fail = (job, message) => {
    settle(job);
    if (job.userData.done) return;
    stats.failedTile(message);
    job.finish(null, null, message);
  };
  const deliver = (f) => {
    const waiting = byKey.get(tileKey(f.level, f.x, f.y));
    if (!waiting) throw new Error(`the batch answered tile ${f.level}/${f.x}/${f.y}, which it did not ask for`);
    for (const job of waiting) deliverTo(job, f);
  };
  const deliverTo = (job, f) => {
    if (f.status !== 200) {
      fail(job, `HTTP ${f.status} for tile ${f.level}/${f.x}/${f.y}: ${errorText(f.body)}`);
      return;
    }
    settle(job);
    if (job.userData.done) return;
    const data = job.userData;
    data.arrived = performance.now();
    data.cache = f.cache;
    const done = (context) => {
      stats.loadedTile(performance.now() - data.t0, f.body.length, f.cache);
      if (data.done) releaseContext(context);
      else job.finish(context, null);
    };
    if (format === 'rgba') {
      let context;
      try {
        context = rgbaTile(f);
      } catch (e) {
        fail(job, `tile ${f.level}/${f.x}/${f.y}: ${e.message}`);
        return;
      }
      done(context);
    } else encodedTile(f, format).then(done, (e) => fail(job, `tile ${f.level}/${f.x}/${f.y}: ${e.message}`));
  };
  fetch(url, { signal: controller.signal, credentials: 'same-origin' })
    .then(async (response) => {
      if (!response.ok) {
        throw new Error(`HTTP ${response.status} for ${url.slice(0, 120)}: ${errorText(new Uint8Array(await response.arrayBuffer()))}`);
      }
      const reader = new FrameReader(deliver);
      const body = response.body.getReader();
      for (;;) {
        const { done, value } = await body.read();
        if (done) break;
        reader.push(value);
      }
      if (!reader.complete) throw new Error('the tile batch ended inside a frame');
      for (const job of [...byKey.values()].flat()) fail(job, `the tile batch ended without tile ${job.src}`);
    })
    .catch((error) => {
      if (error && error.name === 'AbortError') return; // every tile left was aborted
      const message = String(error && error.message ? error.message : error);
      for (const job of [...byKey.values()].flat()) fail(job, message);
    });
}

/** The message of a JSON error body (`{"error": …}`), else its start as text. */
function errorText(bytes) {
  const text = new TextDecoder().decode(bytes);
  try {
    return JSON.parse(text).error || text.slice(0, 200);
  } catch {
    return text.slice(0, 200);
  }
}

const MIME = { png: 'image/png', webp: 'image/webp', jpg: 'image/jpeg' };

/** An encoded tile (PNG, WebP, JPEG), decoded off the main thread, then copied into a canvas. */
async function encodedTile(f, format) {
  const bitmap = await createImageBitmap(new Blob([f.body], { type: MIME[format] }));
  const context = tileContext(bitmap.width, bitmap.height);
  context.drawImage(bitmap, 0, 0);
  bitmap.close();
  return context;
}

/**
 * A raw RGBA tile: no decoding at all, its size from the frame header; the bytes go straight
 * into the tile's canvas (one copy, no ImageBitmap round trip through another thread).
 */
function rgbaTile(f) {
  const { width: w, height: h, body } = f;
  if (!(w > 0 && h > 0) || body.length !== w * h * 4) {
    throw new Error(`raw tile of ${body.length} bytes does not match ${w} × ${h} RGBA`);
  }
  const context = tileContext(w, h);
  context.putImageData(new ImageData(new Uint8ClampedArray(body.buffer, body.byteOffset, body.length), w, h), 0, 0);
  return context;
}
