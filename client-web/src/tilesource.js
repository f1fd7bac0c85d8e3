// An OpenSeadragon tile source over the vtex tile API. Tiles are loaded in batches, one
// request for all the tiles a view needs (batch.js; a browser spends ~3 ms of CPU on every
// request, BENCHMARKS.md "Viewer"), and each tile reports what the server says about it
// (cache hit or miss) and how long it took. Formats: png / webp (lossless), jpg (lossy,
// smallest) and rgba (raw: no decoding, the fastest on a fast link).

import { inPyramid, tileUrl, vtexLevel } from './pyramid.js';
import { FrameReader, MAX_BATCH, batchUrl, readChunks, tileKey } from './batch.js';

/** Read buffers of the batches that finished, for the next ones (batch.js readChunks). */
const readBuffers = [];

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

    // A tile arrives as `{ canvas: ImageBitmap }` (tileImage below): the canvas drawer draws
    // the bitmap as it would draw a tile's canvas.
    createTileCache(cache, image) {
      cache._data = image;
    },

    destroyTileCache(cache) {
      if (cache._data) releaseImage(cache._data);
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
 * A tile's pixels as the canvas drawer takes them: OpenSeadragon asks the tile source for a 2D
 * context and draws its `canvas` (`drawImage(ctx.canvas, …)`, sized by its width and height),
 * so an object whose `canvas` is the tile's ImageBitmap is drawn as is. An ImageBitmap, not a
 * canvas filled with `putImageData`: a new canvas costs the main thread ~0.3 ms a 256 px tile
 * to allocate and premultiply, the bitmap ~0.1 ms (BENCHMARKS.md "Viewer", ingest.mjs).
 */
function tileImage(bitmap) {
  return { canvas: bitmap };
}

/**
 * Frees a tile's pixels now rather than at the next garbage collection. OpenSeadragon then sets
 * the "canvas" to 0 × 0 (its way of freeing a canvas): it gets a plain stand-in instead.
 */
function releaseImage(image) {
  if (typeof image.canvas.close === 'function') image.canvas.close();
  image.canvas = { width: 0, height: 0 };
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
  for (const job of jobs) {
    job.userData.batch = batch;
    job.userData.batchUrl = url; // for tests/browser/trace.mjs
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
    const length = f.body.length;
    const done = (bitmap) => {
      const image = tileImage(bitmap);
      stats.loadedTile(performance.now() - data.t0, length, f.cache);
      if (data.done) releaseImage(image);
      else job.finish(image, null);
    };
    // Both take their bytes now (the body is only valid during this call, FrameReader `reuse`).
    let bitmap;
    try {
      bitmap = format === 'rgba' ? rgbaTile(f) : encodedTile(f, format);
    } catch (e) {
      bitmap = Promise.reject(e);
    }
    bitmap.then(done, (e) => fail(job, `tile ${f.level}/${f.x}/${f.y}: ${e.message}`));
  };
  fetch(url, { signal: controller.signal, credentials: 'same-origin' })
    .then(async (response) => {
      if (!response.ok) {
        throw new Error(`HTTP ${response.status} for ${url.slice(0, 120)}: ${errorText(new Uint8Array(await response.arrayBuffer()))}`);
      }
      // Chunks and split frames live in buffers that are reused: each tile takes its bytes
      // while its frame is handed over (rgbaTile, encodedTile, errorText all copy at once).
      const reader = new FrameReader(deliver, { reuse: true });
      await readChunks(response.body, (chunk) => reader.push(chunk), readBuffers);
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

/** An encoded tile (PNG, WebP, JPEG) as an ImageBitmap, decoded off the main thread. */
function encodedTile(f, format) {
  return createImageBitmap(new Blob([f.body], { type: MIME[format] })); // the Blob copies the bytes
}

/**
 * A raw RGBA tile as an ImageBitmap: no decoding, its size from the frame header, its bytes
 * copied at the call. `premultiplyAlpha: 'none'` keeps them as they are, marked
 * unpremultiplied, instead of converting every pixel here; drawing premultiplies, which for
 * these opaque tiles changes nothing, so the screen shows the server's pixels exactly (the
 * browser tests compare them).
 */
function rgbaTile(f) {
  const { width: w, height: h, body } = f;
  if (!(w > 0 && h > 0) || body.length !== w * h * 4) {
    throw new Error(`raw tile of ${body.length} bytes does not match ${w} × ${h} RGBA`);
  }
  const pixels = new ImageData(new Uint8ClampedArray(body.buffer, body.byteOffset, body.length), w, h);
  return createImageBitmap(pixels, { premultiplyAlpha: 'none' });
}
