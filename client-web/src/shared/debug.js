// Debugging hooks: the objects a page puts on `window` for its browser tests, the benches and a
// developer's console (`window.vtexViewer`, `window.vtDemo`). A page exposes them only when its
// URL asks for them with a `debug` parameter (`/?debug&texture=…`, `/vt.html?debug`); without
// it the pages define no globals of their own.

/** Whether this page's URL asks for its debugging hooks. */
export function debugAsked(search = globalThis.location?.search ?? '') {
  return new URLSearchParams(search).has('debug');
}

const ASKED = debugAsked();

/** Sets `window[name]` to `value` when the page was asked for its hooks; else does nothing. */
export function expose(name, value) {
  if (ASKED) globalThis[name] = value;
}

/**
 * `search` (a query string, with its `?`) with `debug` kept when the page was asked for its hooks,
 * so that the address the viewer writes (the view, after every move) keeps them across a reload.
 * Links made to share (Copy link) are written without it.
 */
export function keepDebug(search, asked = ASKED) {
  if (!asked || debugAsked(search)) return search;
  return `${search}${search.length > 1 ? '&' : search === '?' ? '' : '?'}debug`;
}
