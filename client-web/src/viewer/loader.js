// When OpenSeadragon asks for a view's tiles.

/**
 * Runs `viewer.world.update` in a microtask after a view changed at once (`pan` and `zoom`
 * events with `immediately`; `setView` raises both in one task), at most once per animation
 * frame. OpenSeadragon asks for a view's tiles in its next animation frame, half a frame after
 * the change on average; a view set at once (a jump, a permalink, a zoom without animation)
 * is evaluated right after the change instead, so its batch leaves a frame earlier. Springs
 * reset at once already hold the new view, so the update sees it; OpenSeadragon's own update
 * in the next frame then finds the tiles loading and starts nothing twice.
 */
export function updateEarly(viewer) {
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
