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

/**
 * Fetches `url` (with fetch's `init`) and answers the response when it is a success. A failed
 * fetch or an HTTP error throws an Error naming `what` (when given), the status, the URL and
 * the server's reason; an abort is thrown as it is (an AbortError).
 */
export async function fetchOk(url, what = '', init = undefined) {
  const shown = url.length > QUOTED ? `${url.slice(0, QUOTED)}…` : url;
  const prefix = what ? `${what}: ` : '';
  let response;
  try {
    response = await fetch(url, init);
  } catch (e) {
    if (e?.name === 'AbortError') throw e;
    throw new Error(`${prefix}could not fetch ${shown}: ${e.message}`);
  }
  if (response.ok) return response;
  const reason = errorText(new Uint8Array(await response.arrayBuffer()));
  throw new Error(`${prefix}HTTP ${response.status} for ${shown}${reason ? ` – ${reason}` : ''}`);
}

/** The JSON body of `url` (fetchOk). */
export async function getJson(url, what = '') {
  return (await fetchOk(url, what)).json();
}
