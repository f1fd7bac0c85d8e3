// Bodies of tile frames, as batches and metatiles are answered (vtex_wire::frame; the server's
// api/resources/batch.rs and metatiles.rs). Pure functions, tested in Node.

/** First bytes of every frame: "vtb" and the format version. */
export const MAGIC = [0x76, 0x74, 0x62, 0x01];
export const HEADER_LEN = 32;
/** Most tiles the server accepts in one request. */
export const MAX_BATCH = 256;

/** The key of a tile in a batch: "level/x/y". */
export function tileKey(level, x, y) {
  return `${level}/${x}/${y}`;
}

/**
 * Splits a batch body into frames as its chunks arrive, whatever their boundaries. Each frame
 * is handed to `onFrame` as { level, x, y, status, cache: 'hit' | 'miss' | null, width,
 * height, length, body: Uint8Array } the moment its last byte is pushed. A frame that lies
 * wholly inside one chunk is a view of it; one split across chunks is copied once, into a
 * buffer of its own — or, with `reuse`, into one buffer the reader keeps for every split frame
 * (`body` is then valid only during `onFrame`, which must copy what it keeps): a fresh buffer
 * costs the browser as much to allocate and fill as the copy itself (`bench/viewer/ingest.mjs`
 * compares them).
 */
export class FrameReader {
  constructor(onFrame, { reuse = false } = {}) {
    this.onFrame = onFrame;
    this.scratch = reuse ? new Uint8Array(0) : null;
    this.header = new Uint8Array(HEADER_LEN);
    this.headerFill = 0;
    this.frame = null; // the frame whose body is being filled
    this.bodyFill = 0;
    this.frames = 0;
  }

  /** Consumes one chunk (a Uint8Array). Throws on a frame that is not a batch frame. */
  push(chunk) {
    let i = 0;
    while (i < chunk.length) {
      // A whole frame inside this chunk (most of them: a chunk holds several tiles) is handed over
      // as a view of the chunk, not copied.
      if (!this.frame && this.headerFill === 0 && chunk.length - i >= HEADER_LEN) {
        const frame = parseHeader(chunk.subarray(i, i + HEADER_LEN), false);
        const end = i + HEADER_LEN + frame.length;
        if (end <= chunk.length) {
          frame.body = chunk.subarray(i + HEADER_LEN, end);
          i = end;
          this.frames++;
          this.onFrame(frame);
          continue;
        }
      }
      if (!this.frame) {
        const n = Math.min(HEADER_LEN - this.headerFill, chunk.length - i);
        this.header.set(chunk.subarray(i, i + n), this.headerFill);
        this.headerFill += n;
        i += n;
        if (this.headerFill < HEADER_LEN) return;
        this.headerFill = 0;
        this.frame = parseHeader(this.header, !this.scratch);
        if (this.scratch) {
          if (this.scratch.length < this.frame.length) this.scratch = new Uint8Array(this.frame.length);
          this.frame.body = this.scratch.subarray(0, this.frame.length);
        }
        this.bodyFill = 0;
      }
      const body = this.frame.body;
      const n = Math.min(body.length - this.bodyFill, chunk.length - i);
      body.set(chunk.subarray(i, i + n), this.bodyFill);
      this.bodyFill += n;
      i += n;
      if (this.bodyFill === body.length) {
        const frame = this.frame;
        this.frame = null;
        this.frames++;
        this.onFrame(frame);
      }
    }
  }

  /** True when the stream ended between frames (not inside one). */
  get complete() {
    return !this.frame && this.headerFill === 0;
  }
}

/** Size of the buffer a batch body is read into: the largest chunk Chromium hands over (2 MiB). */
export const READ_BUFFER_BYTES = 2 << 20;

/**
 * Reads the byte stream `body` to its end, handing each chunk to `push` (a Uint8Array that is
 * valid only during the call). Where the stream supports it (fetch bodies in Chromium), every
 * chunk is read into one buffer that goes back and forth between the stream and `push`,
 * taken from and returned to `buffers` (a pool shared by the batches): a default reader
 * allocates a fresh ArrayBuffer for every chunk, which costs the page's main thread CPU in
 * proportion to the bytes (`bench/viewer/ingest.mjs` compares the two readers).
 */
export async function readChunks(body, push, buffers = []) {
  let reader;
  try {
    reader = body.getReader({ mode: 'byob' });
  } catch {
    reader = null; // not a byte stream
  }
  if (!reader) {
    const plain = body.getReader();
    for (;;) {
      const { done, value } = await plain.read();
      if (done) return;
      push(value);
    }
  }
  let buffer = buffers.pop() || new ArrayBuffer(READ_BUFFER_BYTES);
  for (;;) {
    const { done, value } = await reader.read(new Uint8Array(buffer));
    // The stream hands the buffer back (transferred) with every read, also the last one.
    buffer = value.buffer;
    if (done) break;
    push(value);
  }
  buffers.push(buffer); // a failed or aborted read keeps its buffer: it is not reused then
}

/** The header in `h` (32 bytes); with `allocate`, a buffer of its body's length to fill. */
function parseHeader(h, allocate = true) {
  for (let i = 0; i < MAGIC.length; i++) {
    if (h[i] !== MAGIC[i]) throw new Error(`not a vtex tile batch frame (header bytes ${[...h.subarray(0, 4)]})`);
  }
  const v = new DataView(h.buffer, h.byteOffset, HEADER_LEN);
  const cache = h[18];
  return {
    level: v.getUint32(4, true),
    x: v.getUint32(8, true),
    y: v.getUint32(12, true),
    status: v.getUint16(16, true),
    cache: cache === 1 ? 'hit' : cache === 2 ? 'miss' : null,
    width: v.getUint32(20, true),
    height: v.getUint32(24, true),
    length: v.getUint32(28, true),
    body: allocate ? new Uint8Array(v.getUint32(28, true)) : null,
  };
}
