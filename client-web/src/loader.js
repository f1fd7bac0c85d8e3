// Tile request scheduling on top of OpenSeadragon's image loader.

/** Levels coarser than the finest at which a view's preview is loaded (≤ 2 × 2 tiles). */
export const PREVIEW_STEPS = 3;

/**
 * Whether a tile of OpenSeadragon level `level` is worth fetching while the view's finest
 * level is `finest` (OSD levels count up from the single-tile level 0): the finest level, one
 * preview level PREVIEW_STEPS coarser, and the single whole-texture tile, the fallback under
 * everything (OSD never evicts it).
 */
export function wantedLevel(level, finest) {
  return level === finest || level === finest - PREVIEW_STEPS || level === 0;
}

/**
 * Two changes to how OpenSeadragon 5 feeds its image loader, both measured with
 * `node bench/viewer/bench.mjs --trace` (BENCHMARKS.md, "Viewer"):
 *
 * 1. It empties the loader's queue after every draw (`drawWorld` in viewer.js), so a request
 *    slot freed between two frames stays idle until the next frame. Here the queue is kept
 *    until the start of the next update instead: the loader starts the next queued tile the
 *    moment one finishes, and every update still rebuilds the queue from what the current
 *    view needs, so tiles of views already left are never fetched.
 * 2. While tiles of the finest level are missing it fetches every coarser level under them
 *    too, coarsest first, for a progressive preview: a third of a view's requests, and the
 *    mid levels are the dearest to synthesize. Here only `wantedLevel` levels are fetched: a
 *    preview of at most 2 × 2 tiles comes first, then the finest level. Coarser tiles already
 *    in memory (the previous view's) are still drawn under missing ones.
 *
 * 3. It lets a started tile load to the end even when the view has left it. With every tile of
 *    a view requested at once (the tile source batches them, tilesource.js), a fast zoom
 *    would have the server synthesize every intermediate view. Here, after each update that
 *    re-evaluated the view, every started tile the update did not touch (OpenSeadragon stamps
 *    `lastTouchTime` on each tile the view still needs) is aborted: its tile goes back to not
 *    loading, so a later view that needs it asks again, and the tile source aborts a request
 *    once none of its tiles is wanted. Removing a tiled image aborts all of its tiles.
 *
 * 4. It asks for a view's tiles in its next animation frame, ~8 ms after the view changed on
 *    average. Here a view set at once (a jump, a permalink, a zoom without animation) is
 *    evaluated in the same task, right after the change: its batch leaves a frame earlier.
 *    At most one such early update runs per frame, so a stream of immediate pans costs no more
 *    than OpenSeadragon's own updates.
 *
 * OpenSeadragon adds jobs only while it updates its tiled images; here the jobs of one update
 * are collected, filtered against the finest level among them, and handed to the loader in
 * OpenSeadragon's order. Closing the viewer empties the queue at once, as before.
 */
export function scheduleTiles(viewer) {
  const loader = viewer.imageLoader;
  const clear = loader.clear.bind(loader);
  loader.clear = () => {};
  const addJob = loader.addJob.bind(loader);
  let batch = null;
  loader.addJob = (options) => (batch ? batch.push(options) : addJob(options));
  const world = viewer.world;
  const update = world.update.bind(world);
  world.update = (viewportChanged) => {
    clear();
    batch = [];
    const t = Date.now(); // OpenSeadragon's clock for lastTouchTime ($.now)
    try {
      return update(viewportChanged);
    } finally {
      const jobs = batch;
      batch = null;
      for (let i = 0; i < world.getItemCount(); i++) dropStale(loader, world.getItemAt(i), t, jobs);
      const finest = Math.max(...jobs.map((o) => (o.tile && Number.isInteger(o.tile.level) ? o.tile.level : -Infinity)));
      for (const options of jobs) {
        const level = options.tile && options.tile.level;
        if (Number.isInteger(level) && !wantedLevel(level, finest)) {
          if (typeof options.abort === 'function') options.abort(); // the tile is not loading after all
        } else {
          addJob(options);
        }
      }
    }
  };
  viewer.addHandler('close', clear);
  updateEarly(viewer);
  world.addHandler('remove-item', (e) => {
    for (const job of [...(e.item.source.vtexInFlight || [])]) if (ownTile(e.item, job.tile)) abortStarted(loader, job);
  });
}

/**
 * Runs `viewer.world.update` in a microtask after a view changed at once (`pan` and `zoom`
 * events with `immediately`; `setView` raises both in one task), at most once per animation
 * frame. Springs reset at once already hold the new view, so the update sees it; OpenSeadragon's
 * own update in the next frame then finds the tiles loading and starts nothing twice.
 */
function updateEarly(viewer) {
  let armed = true;
  const changed = (event) => {
    if (!event.immediately || !armed) return;
    armed = false;
    queueMicrotask(() => {
      requestAnimationFrame(() => (armed = true));
      if (viewer.world.getItemCount() > 0) viewer.world.update(true);
    });
  };
  viewer.addHandler('pan', changed);
  viewer.addHandler('zoom', changed);
}

/**
 * Aborts the started jobs of `item` that the update begun at `t` did not touch, if that update
 * re-evaluated the item's tiles: it touched one of them or a tile it now draws (OpenSeadragon
 * skips the evaluation when nothing changed, and then nothing is stale either).
 */
function dropStale(loader, item, t, jobs) {
  const started = item.source.vtexInFlight;
  if (!started || started.size === 0) return;
  const touched = (tile) => tile && tile.lastTouchTime >= t;
  const evaluated =
    jobs.some((o) => o.source === item.source && touched(o.tile)) || item.getTilesToDraw().some((d) => d.currentTime >= t);
  if (!evaluated) return;
  for (const job of [...started]) if (ownTile(item, job.tile) && !touched(job.tile)) abortStarted(loader, job);
}

/**
 * Whether `tile` is one of `item`'s. The navigator shows the same tile source through tiled
 * images of its own (own tiles, own loader, own updates): its jobs are not this viewer's.
 */
function ownTile(item, tile) {
  const m = item.tilesMatrix;
  return Boolean(tile && m && m[tile.level] && m[tile.level][tile.x] && m[tile.level][tile.x][tile.y] === tile);
}

/**
 * Ends a started job without finishing it (finishing without data would mark its tile as
 * missing for good and log an error): the tile source's abort, the tile back to not loading,
 * OpenSeadragon's timeout cleared and its count of jobs in progress decremented.
 */
export function abortStarted(loader, job) {
  if (job.jobId) clearTimeout(job.jobId);
  job.abort(); // ImageJob.start wrapped it: the source's downloadTileAbort, then tile.loading = false
  loader.jobsInProgress = Math.max(0, loader.jobsInProgress - 1);
}
