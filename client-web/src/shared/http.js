// vtex's answers as the pages and Workers read them: a response that failed becomes an error
// that says what was asked for and why it was refused (vtex answers errors as
// `{"error": "…"}`; a proxy or a static file server may answer text).

/** Characters of a URL or a body quoted in a message. */
const QUOTED = 200;

/** The message of an error body (bytes): its JSON `error`, else its start as text. */
export function errorText(bytes) {
  const text = new TextDecoder().decode(bytes);
  try {
    return JSON.parse(text).error || text.slice(0, QUOTED);
  } catch {
    return text.slice(0, QUOTED);
  }
}

/** Times a read answered `503` is asked again: vtex (or a replica behind nginx) sheds load or
 * has a budget spent for a moment, and says when to come back in `Retry-After`. */
export const RETRIES_503 = 3;
/** The longest wait before asking again, in seconds, whatever `Retry-After` says. */
const MAX_RETRY_WAIT = 5;

/** Seconds to wait before asking again, from a `Retry-After` header (seconds or an HTTP date). */
export function retryDelay(header) {
  const seconds = header === null || header.trim() === '' ? NaN : Number(header);
  const wait = Number.isFinite(seconds) ? seconds : (Date.parse(header ?? '') - Date.now()) / 1000;
  return Math.min(MAX_RETRY_WAIT, Math.max(0, Number.isFinite(wait) ? wait : 1));
}

/** Waits `ms`, or rejects with `signal`'s reason (an AbortError) once it aborts. */
function pause(ms, signal) {
  return new Promise((resolve, reject) => {
    if (signal?.aborted) return reject(signal.reason);
    const stop = () => {
      clearTimeout(timer);
      reject(signal.reason);
    };
    const timer = setTimeout(() => {
      signal?.removeEventListener('abort', stop);
      resolve();
    }, ms);
    signal?.addEventListener('abort', stop, { once: true });
  });
}

/**
 * Fetches `url` (with fetch's `init`) and answers the response when it is a success. A read
 * (GET) answered `503` is asked again after its `Retry-After`, up to {@link RETRIES_503} times,
 * as browsers do not. A failed fetch or an HTTP error throws an Error naming `what` (when
 * given), the status, the URL and the server's reason; an abort is thrown as it is (an
 * AbortError).
 */
export async function fetchOk(url, what = '', init = undefined) {
  const shown = url.length > QUOTED ? `${url.slice(0, QUOTED)}…` : url;
  const prefix = what ? `${what}: ` : '';
  const read = (init?.method ?? 'GET').toUpperCase() === 'GET';
  let response;
  for (let retries = read ? RETRIES_503 : 0; ; retries--) {
    try {
      response = await fetch(url, init);
    } catch (e) {
      if (e?.name === 'AbortError') throw e;
      throw new Error(`${prefix}could not fetch ${shown}: ${e.message}`);
    }
    if (response.status !== 503 || retries === 0) break;
    await response.body?.cancel();
    await pause(retryDelay(response.headers.get('retry-after')) * 1000, init?.signal);
  }
  if (response.ok) return response;
  const reason = errorText(new Uint8Array(await response.arrayBuffer()));
  throw new Error(`${prefix}HTTP ${response.status} for ${shown}${reason ? ` – ${reason}` : ''}`);
}

/** The JSON body of `url` (fetchOk). */
export async function getJson(url, what = '') {
  return (await fetchOk(url, what)).json();
}
