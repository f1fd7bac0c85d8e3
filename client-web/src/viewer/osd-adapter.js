// Everything the viewer takes from OpenSeadragon beyond its public API, in one place.
//
// The rest of the viewer uses documented members only: the tile source's batch API
// (`batchEnabled`, `downloadTileBatchStart`, …), `job.finish(data, request, dataType)` and
// `job.fail`, the data-type converter (`OpenSeadragon.converter`), the drawer's
// `getSupportedDataFormats`, `defaultOptions` and `internalCacheCreate`, and the viewer's events.
// What is left here depends on how this one release works inside; `PRIVATE_MEMBERS` lists it,
// and the browser tests check every entry against the library the page loads, so an upgrade
// that moves any of it fails there rather than on screen.

/** The OpenSeadragon release this module was written against. */
export const OSD_VERSION = '6.1.1';

/**
 * The private members used below, with what `typeof` gives for each on the loaded library.
 * `path` starts at the OpenSeadragon namespace (`CanvasDrawer.prototype._createDrawingElement`)
 * or, for members set per instance, at an object the test builds (`viewer.imageLoader.…`).
 */
export const PRIVATE_MEMBERS = [
  // Overridden: the canvas the drawer draws on, made opaque.
  { path: 'CanvasDrawer.prototype._createDrawingElement', type: 'function' },
  // Overridden: whether the drawer enlarges tiles by a pixel to hide seams (only while smoothing).
  { path: 'CanvasDrawer.prototype.minimumOverlapRequired', type: 'function' },
  // Read by the canvas drawer on the data a drawer's internal cache holds: it draws `.canvas`.
  { path: 'CanvasDrawer.prototype._drawTile', type: 'function', reads: 'rendered.canvas' },
  // Wrapped: emptying the loader after every draw also drops batches not yet flushed; read:
  // the loader's limit on concurrent jobs (none: no queue to empty).
  { path: 'viewer.imageLoader.clear', type: 'function' },
  { path: 'viewer.imageLoader.jobLimit', type: 'number' },
  { path: 'viewer.navigator.imageLoader.clear', type: 'function' },
  // Wrapped: the jobs of one update, filtered by level before they reach the batch.
  { path: 'viewer.imageLoader.addJob', type: 'function' },
];

/** Throws unless `OSD` is the release this module was written against. */
export function checkVersion(OSD) {
  const found = OSD && OSD.version && OSD.version.versionStr;
  if (found !== OSD_VERSION) {
    const message = `vtex viewer: written for OpenSeadragon ${OSD_VERSION}, but ${found || 'no OpenSeadragon'} is loaded; check every entry of osd-adapter.js PRIVATE_MEMBERS against it before changing OSD_VERSION`;
    console.error(message);
    throw new Error(message);
  }
}

/**
 * OpenSeadragon's canvas drawer (exact pixels at 1:1, no GPU), drawing the ImageBitmaps the tile
 * source delivers as they are and onto an opaque canvas.
 *
 * - Tiles arrive as data type "imageBitmap" (tilesource.js). The stock canvas drawer takes only
 *   "context2d", and the pipeline's conversion would copy every tile into a new canvas; this
 *   drawer declares "imageBitmap" and hands the canvas drawer, through its private cache, an
 *   object whose `canvas` is the bitmap: what the canvas drawer reads of a context is its
 *   `canvas`, which it passes to `drawImage`.
 * - The canvas is opaque (`alpha: false`): tiles are opaque (tilesource.js `hasTransparency`)
 *   and the background black, which an opaque canvas shows where nothing is drawn; the
 *   compositor then leaves out what lies under the canvas instead of blending over it.
 * - The drawer enlarges every tile by a screen pixel to hide the seams smoothing leaves at
 *   fractional tile edges; that stretch would shift texels, so it is only asked for while
 *   smoothing is on (`setImageSmoothingEnabled`).
 */
export function vtexDrawer(OSD) {
  checkVersion(OSD);
  return class VtexCanvasDrawer extends OSD.CanvasDrawer {
    get defaultOptions() {
      // The bitmap wrapper is made when a tile is first drawn, with no conversion to await.
      return { usePrivateCache: true, preloadCache: false };
    }

    getSupportedDataFormats() {
      return ['imageBitmap'];
    }

    internalCacheCreate(cache) {
      return { canvas: cache.data };
    }

    setImageSmoothingEnabled(enabled) {
      this.vtexSmoothing = Boolean(enabled);
      super.setImageSmoothingEnabled(enabled);
    }

    minimumOverlapRequired() {
      return this.vtexSmoothing !== false;
    }

    _createDrawingElement() {
      const canvas = super._createDrawingElement();
      canvas.getContext('2d', { alpha: false }); // the drawer's own getContext('2d') returns this one
      return canvas;
    }
  };
}

/**
 * Keeps the tile batches OpenSeadragon is still collecting when it empties its image loader
 * after every draw. A view's tiles are staged into a batch while the world updates and the batch
 * is flushed after `batchTimeout`; the draw that follows the update in the same frame empties the
 * loader, and OpenSeadragon's `clear` drops the staged batch without starting or aborting its
 * jobs, which leaves their tiles marked as loading for good. With no limit on concurrent jobs
 * (`imageLoaderLimit: 0`) the loader has no other queue to empty. Closing the viewer still
 * empties it all.
 */
export function keepBatchesOnDraw(viewer) {
  for (const loader of [viewer.imageLoader, viewer.navigator && viewer.navigator.imageLoader]) {
    if (!loader) continue;
    const clear = loader.clear.bind(loader);
    loader.clear = () => {
      if (loader.jobLimit) clear();
    };
    viewer.addHandler('close', clear);
  }
}

/** Levels coarser than the finest at which a view's preview is loaded (≤ 2 × 2 tiles). */
export const PREVIEW_STEPS = 3;

/**
 * Whether a tile of OpenSeadragon level `level` is worth fetching while the finest level a view
 * asks for is `finest` (OSD levels count up from the single-tile level 0): the finest level, one
 * preview level PREVIEW_STEPS coarser, and the single whole-texture tile, the fallback under
 * everything (OSD never evicts it).
 */
export function wantedLevel(level, finest) {
  return level === finest || level === finest - PREVIEW_STEPS || level === 0;
}

/**
 * Fetches only `wantedLevel` levels of what the viewer's own tiled images ask for. While tiles of
 * the finest level are missing OpenSeadragon asks for every coarser level under them too, for a
 * progressive preview: a third of a view's tiles, and the mid levels are the dearest to
 * synthesize. The jobs OpenSeadragon adds in one task (one update: every tile the view needs)
 * are collected and, in a microtask, handed on in its order when wanted; the others are given
 * back (`abort`: the tile is not loading after all, and a later view may ask for it again).
 * They reach the tile source's batch either way before it is flushed. Coarser tiles already in
 * memory are still drawn under missing ones.
 */
export function fetchWantedLevels(viewer) {
  const loader = viewer.imageLoader;
  const addJob = loader.addJob.bind(loader);
  let pending = null;
  const flush = () => {
    const jobs = pending;
    pending = null;
    const finest = Math.max(...jobs.map((o) => (o.tile && Number.isInteger(o.tile.level) ? o.tile.level : -Infinity)));
    for (const options of jobs) {
      const level = options.tile && options.tile.level;
      if (Number.isInteger(level) && !wantedLevel(level, finest)) {
        if (typeof options.abort === 'function') options.abort();
      } else {
        addJob(options);
      }
    }
  };
  loader.addJob = (options) => {
    if (!pending) {
      pending = [];
      queueMicrotask(flush);
    }
    pending.push(options);
    return false; // not started at once: the batch starts it
  };
}
