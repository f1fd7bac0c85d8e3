//! Prometheus metrics, served as text at `/metrics`.

use prometheus::{
    Encoder, Histogram, HistogramOpts, HistogramVec, IntCounter, IntCounterVec, IntGauge, Opts, Registry, TextEncoder,
};

/// Levels with their own hit/miss series; deeper levels share the last one.
const LEVEL_SERIES: usize = 64;

pub struct Metrics {
    registry: Registry,
    pub requests: IntCounterVec,
    pub request_seconds: HistogramVec,
    pub bytes_out: IntCounter,
    hits: Vec<IntCounter>,
    misses: Vec<IntCounter>,
    pub syntheses: IntCounter,
    pub synthesis_seconds: Histogram,
    pub encode_seconds: HistogramVec,
    pub syntheses_in_flight: IntGauge,
    pub cache_bytes: IntGauge,
    pub cache_budget_bytes: IntGauge,
    pub cache_entries: IntGauge,
    pub cache_evictions: IntGauge,
    pub textures: IntGauge,
}

fn must<T>(r: prometheus::Result<T>) -> T {
    r.expect("metric definitions are static and valid")
}

impl Metrics {
    pub fn new() -> Self {
        let registry = Registry::new();
        let fast =
            vec![0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0];
        let requests = must(IntCounterVec::new(
            Opts::new("vtex_http_requests_total", "HTTP requests by route, method and status"),
            &["route", "method", "status"],
        ));
        let request_seconds = must(HistogramVec::new(
            HistogramOpts::new("vtex_http_request_duration_seconds", "HTTP request latency by route")
                .buckets(fast.clone()),
            &["route"],
        ));
        let bytes_out = must(IntCounter::new("vtex_http_response_bytes_total", "Response body bytes sent"));
        let hits_vec = must(IntCounterVec::new(
            Opts::new("vtex_tile_cache_hits_total", "Tiles served from the cache, by level"),
            &["level"],
        ));
        let misses_vec = must(IntCounterVec::new(
            Opts::new("vtex_tile_cache_misses_total", "Tiles not in the cache, by level"),
            &["level"],
        ));
        let syntheses =
            must(IntCounter::new("vtex_syntheses_total", "Tile syntheses run (a coalesced miss counts once)"));
        let synthesis_seconds = must(Histogram::with_opts(
            HistogramOpts::new("vtex_synthesis_seconds", "Time to render one tile or region").buckets(fast.clone()),
        ));
        let encode_seconds = must(HistogramVec::new(
            HistogramOpts::new("vtex_encode_seconds", "Time to encode one tile or region, by format").buckets(fast),
            &["format"],
        ));
        let syntheses_in_flight = must(IntGauge::new("vtex_syntheses_in_flight", "Syntheses running now"));
        let cache_bytes = must(IntGauge::new("vtex_tile_cache_bytes", "Bytes held by the tile cache"));
        let cache_budget_bytes = must(IntGauge::new("vtex_tile_cache_budget_bytes", "Byte budget of the tile cache"));
        let cache_entries = must(IntGauge::new("vtex_tile_cache_entries", "Tiles held by the tile cache"));
        let cache_evictions = must(IntGauge::new("vtex_tile_cache_evictions", "Tiles evicted since start"));
        let textures = must(IntGauge::new("vtex_textures", "Textures in the store"));
        for c in [
            Box::new(requests.clone()) as Box<dyn prometheus::core::Collector>,
            Box::new(request_seconds.clone()),
            Box::new(bytes_out.clone()),
            Box::new(hits_vec.clone()),
            Box::new(misses_vec.clone()),
            Box::new(syntheses.clone()),
            Box::new(synthesis_seconds.clone()),
            Box::new(encode_seconds.clone()),
            Box::new(syntheses_in_flight.clone()),
            Box::new(cache_bytes.clone()),
            Box::new(cache_budget_bytes.clone()),
            Box::new(cache_entries.clone()),
            Box::new(cache_evictions.clone()),
            Box::new(textures.clone()),
        ] {
            must(registry.register(c));
        }
        // Label lookups hash strings; tiles are the hot path, so resolve them once.
        let levels: Vec<String> = (0..LEVEL_SERIES).map(|l| l.to_string()).collect();
        let hits = levels.iter().map(|l| hits_vec.with_label_values(&[l.as_str()])).collect();
        let misses = levels.iter().map(|l| misses_vec.with_label_values(&[l.as_str()])).collect();
        Metrics {
            registry,
            requests,
            request_seconds,
            bytes_out,
            hits,
            misses,
            syntheses,
            synthesis_seconds,
            encode_seconds,
            syntheses_in_flight,
            cache_bytes,
            cache_budget_bytes,
            cache_entries,
            cache_evictions,
            textures,
        }
    }

    pub fn cache_hit(&self, level: u32) {
        self.hits[(level as usize).min(LEVEL_SERIES - 1)].inc();
    }

    pub fn cache_miss(&self, level: u32) {
        self.misses[(level as usize).min(LEVEL_SERIES - 1)].inc();
    }

    /// The Prometheus text exposition of every metric.
    pub fn render(&self) -> String {
        let mut out = Vec::new();
        TextEncoder::new().encode(&self.registry.gather(), &mut out).expect("text encoding to memory cannot fail");
        String::from_utf8(out).expect("the text format is UTF-8")
    }
}

impl Default for Metrics {
    fn default() -> Self {
        Self::new()
    }
}
