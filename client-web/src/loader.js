// Tile request scheduling on top of OpenSeadragon's image loader.

/**
 * OpenSeadragon 5 empties its image loader's queue after every draw (`drawWorld` in
 * viewer.js), so a request slot freed between two frames stays idle until the next frame:
 * with N requests in flight, a view of 32 tiles takes at least 32 / N frames however fast the
 * server answers. Here the queue is kept until the start of the next update instead: the
 * loader starts the next queued tile the moment one finishes, and every update still rebuilds
 * the queue from what the current view needs first, so tiles of views already left are never
 * fetched. (Closing the viewer empties the queue at once, as before.)
 */
export function keepQueueUntilNextUpdate(viewer) {
  const loader = viewer.imageLoader;
  const clear = loader.clear.bind(loader);
  loader.clear = () => {};
  const world = viewer.world;
  const update = world.update.bind(world);
  world.update = (viewportChanged) => {
    clear();
    return update(viewportChanged);
  };
  viewer.addHandler('close', clear);
}
