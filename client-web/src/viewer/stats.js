// Live tile statistics: counts, bytes, server cache hits and latency percentiles.

/** Value at quantile `q` (0..1) of `values` (nearest-rank on a sorted copy); NaN if empty. */
export function percentile(values, q) {
  if (values.length === 0) return NaN;
  const s = Float64Array.from(values).sort();
  const rank = Math.min(s.length, Math.max(1, Math.ceil(q * s.length)));
  return s[rank - 1];
}

/** Accumulates what the tile loader observes. Latencies keep a bounded recent window. */
export class TileStats {
  constructor(window = 1000) {
    this.window = window;
    this.reset();
  }

  reset() {
    this.requested = 0; // tiles asked for
    this.batches = 0; // requests made for them (the metatiles holding them)
    this.loaded = 0; // tiles decoded and handed to OpenSeadragon
    this.failed = 0;
    this.aborted = 0;
    this.serverHits = 0; // X-Vtex-Cache: hit
    this.serverMisses = 0; // X-Vtex-Cache: miss
    this.browserCached = 0; // answered from the browser's HTTP cache (no bytes on the wire)
    this.bodyBytes = 0; // tile bodies received (encoded PNG bytes)
    this.wireBytes = 0; // bytes on the wire incl. headers (Resource Timing transferSize)
    this.latencies = [];
    this.lastError = null;
  }

  started() {
    this.requested++;
  }

  batchStarted() {
    this.batches++;
  }

  /** One tile arrived: `ms` from request to decoded image, `cache` the X-Vtex-Cache header. */
  loadedTile(ms, bodyBytes, cache) {
    this.loaded++;
    this.bodyBytes += bodyBytes;
    if (cache === 'hit') this.serverHits++;
    else if (cache === 'miss') this.serverMisses++;
    this.latencies.push(ms);
    if (this.latencies.length > this.window) this.latencies.splice(0, this.latencies.length - this.window);
  }

  failedTile(message) {
    this.failed++;
    this.lastError = message;
  }

  abortedTile() {
    this.aborted++;
  }

  /** A Resource Timing entry for a tile request: transferSize 0 with a body means the browser cache. */
  resource(entry) {
    this.wireBytes += entry.transferSize || 0;
    if (entry.transferSize === 0 && entry.decodedBodySize > 0) this.browserCached++;
  }

  snapshot() {
    return {
      requested: this.requested,
      batches: this.batches,
      loaded: this.loaded,
      failed: this.failed,
      aborted: this.aborted,
      serverHits: this.serverHits,
      serverMisses: this.serverMisses,
      browserCached: this.browserCached,
      bodyBytes: this.bodyBytes,
      wireBytes: this.wireBytes,
      p50: percentile(this.latencies, 0.5),
      p95: percentile(this.latencies, 0.95),
      lastError: this.lastError,
    };
  }
}

/** "1.5 MB"-style byte counts (powers of 1000, as transfer sizes usually are). */
export function formatBytes(n) {
  if (!Number.isFinite(n)) return '–';
  const units = ['B', 'kB', 'MB', 'GB', 'TB', 'PB'];
  let u = 0;
  while (Math.abs(n) >= 1000 && u < units.length - 1) {
    n /= 1000;
    u++;
  }
  return `${u === 0 ? n : n.toFixed(n < 10 ? 2 : n < 100 ? 1 : 0)} ${units[u]}`;
}

/** "1 : 2,400,000"-style ratio of the explicit texture's bytes to the encoding's. */
export function formatRatio(explicitBytes, encodingBytes) {
  if (!(encodingBytes > 0)) return '–';
  const r = explicitBytes / encodingBytes;
  const shown = r >= 100 ? Math.round(r).toLocaleString('en-US') : r.toFixed(r >= 10 ? 1 : 2);
  return `${shown} : 1`;
}
