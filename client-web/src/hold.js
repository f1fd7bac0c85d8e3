// Paint holding for views set at once: a jump, a link, a zoom or a pan without animation.
//
// OpenSeadragon draws a new view in the very next frame from whatever it has: the previous
// view's tiles and coarser ones, enlarged. When the new view's own tiles come within a frame or
// two (the server has them), that stand-in frame is on screen for one or two frames, a blurred
// flash, and on the 2-core test machine it costs ~10 ms of the page's main thread plus the
// compositor's time while the tiles stream in: the tiles then wait behind it to reach
// OpenSeadragon (BENCHMARKS.md "Viewer", session 7). Here the canvas keeps the complete view it
// shows until every tile of the new view is in, or `ms` have passed; then OpenSeadragon draws
// as it would have, stand-ins included. Browsers hold a page's last paint across a navigation
// for the same reason.
//
// Only a complete view is held, and only for a change made at once. Anything else ends the
// hold at once: an animated change, another change in a later task (the next step of a drag or
// a pinch, so a gesture is held back one frame at most), a tiled image added or removed.

/** How long a view set at once may keep the previous view on screen, ms. */
export const HOLD_MS = 50;

/**
 * Makes `viewer`'s drawer hold the canvas after a view set at once, as above. Wraps the
 * drawer's current `draw` (call it after other wrappers of `draw`). Returns the hold's
 * settings and counts, live: `ms` (0 switches holding off), `holds` started, frames `held`
 * (not drawn), holds that `expired` (the view drawn incomplete at the deadline).
 */
export function holdPaint(viewer, { ms = HOLD_MS, now = () => performance.now() } = {}) {
  const hold = { ms, holds: 0, held: 0, expired: 0 };
  const drawer = viewer.drawer;
  if (!drawer || typeof drawer.draw !== 'function') return hold;
  let until = 0; // the deadline of the hold in progress, 0 when none
  let starting = false; // the change that started it is still in its task
  let timer = 0;
  const end = () => {
    until = 0;
    clearTimeout(timer);
  };
  const complete = (items) => {
    const shown = items.filter((item) => item.opacity !== 0);
    return shown.length > 0 && shown.every((item) => item.getFullyLoaded());
  };
  const items = () => Array.from({ length: viewer.world.getItemCount() }, (_, i) => viewer.world.getItemAt(i));
  const changed = (event) => {
    // setView raises a zoom and a pan in one task: one change.
    if (starting) return;
    end();
    // What the tiled images report now is still the view on the canvas: the new view is
    // evaluated after this task (loader.js), or in the next frame.
    if (!event.immediately || hold.ms <= 0 || !complete(items())) return;
    until = now() + hold.ms;
    hold.holds++;
    starting = true;
    queueMicrotask(() => (starting = false));
  };
  viewer.addHandler('pan', changed);
  viewer.addHandler('zoom', changed);
  viewer.world.addHandler('add-item', end);
  viewer.world.addHandler('remove-item', end);

  const draw = drawer.draw.bind(drawer);
  drawer.draw = (drawn) => {
    if (until) {
      const t = now();
      const whole = complete(drawn);
      if (!whole && t < until) {
        hold.held++;
        // OpenSeadragon draws again when a tile arrives; if none completes the view in time,
        // the deadline does.
        clearTimeout(timer);
        timer = setTimeout(() => viewer.forceRedraw(), until - t);
        return;
      }
      if (!whole) hold.expired++;
      end();
    }
    draw(drawn);
  };
  return hold;
}
