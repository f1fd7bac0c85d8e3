// Tile request scheduling on top of OpenSeadragon's image loader.

/**
 * Two changes to how OpenSeadragon 5 (`immediateRender: true`, finest level first) feeds its
 * image loader, both measured with `node tests/browser/bench.mjs --trace`:
 *
 * 1. It empties the loader's queue after every draw (`drawWorld` in viewer.js), so a request
 *    slot freed between two frames stays idle until the next frame. Here the queue is kept
 *    until the start of the next update instead: the loader starts the next queued tile the
 *    moment one finishes, and every update still rebuilds the queue from what the current
 *    view needs, so tiles of views already left are never fetched.
 * 2. While tiles of the finest level are missing it also queues the coarser levels under them,
 *    for a blurry preview. Those are a third of a view's requests, and coarse tiles are the
 *    dearest to synthesize, so they delay the finest tiles more than they help: only the finest
 *    level being loaded is kept in the queue. Coarser tiles already in memory (the previous
 *    view's, the navigator's whole-texture tiles) are still drawn under missing ones.
 *
 * Closing the viewer empties the queue at once, as before.
 */
export function scheduleTiles(viewer) {
  const loader = viewer.imageLoader;
  const clear = loader.clear.bind(loader);
  loader.clear = () => {};
  const world = viewer.world;
  const update = world.update.bind(world);
  world.update = (viewportChanged) => {
    clear();
    const out = update(viewportChanged);
    keepFinestLevel(loader);
    return out;
  };
  viewer.addHandler('close', clear);
}

/** Drops queued jobs of levels coarser than the finest one queued (OSD levels: higher = finer). */
function keepFinestLevel(loader) {
  const queue = loader.jobQueue;
  if (queue.length < 2) return;
  let finest = -Infinity;
  for (const job of queue) finest = Math.max(finest, job.tile.level);
  const kept = [];
  for (const job of queue) {
    if (job.tile.level === finest) kept.push(job);
    else if (typeof job.abort === 'function') job.abort(); // marks the tile as not loading
  }
  loader.jobQueue = kept;
}
