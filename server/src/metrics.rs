//! Prometheus metrics, served as text at `/metrics`, named as Prometheus asks: counters end in
//! `_total`, quantities carry their base unit (`_seconds`, `_bytes`), and the process's own
//! `process_*` family (memory, CPU, descriptors, start time) is collected on Linux.

use prometheus::{
    Encoder, HistogramOpts, HistogramVec, IntCounter, IntCounterVec, IntGauge, IntGaugeVec, Opts, Registry, TextEncoder,
};
use vtex_synth::Resources;

/// The `route` label of the requests no route matched, which the static viewer's files
/// answer: one fixed label, so paths that do not exist cannot add series.
pub const STATIC: &str = "static";

/// Levels with their own hit/miss series; deeper levels share the last one.
const LEVEL_SERIES: usize = 64;

pub struct Metrics {
    registry: Registry,
    requests: IntCounterVec,
    request_seconds: HistogramVec,
    pub bytes_out: IntCounter,
    hits: Vec<IntCounter>,
    misses: Vec<IntCounter>,
    pub syntheses: IntCounter,
    pub synthesis_seconds: HistogramVec,
    pub encode_seconds: HistogramVec,
    /// Whole tile batches, from the request to the body's end, by how the body ended.
    pub batch_seconds: HistogramVec,
    pub syntheses_in_flight: IntGauge,
    /// Renders stopped before their end: nobody waited for them any more, or shutdown.
    pub syntheses_stopped: IntCounter,
    /// Misses answered 503 because the synthesis queue was full.
    pub syntheses_shed: IntCounter,
    pub syntheses_queued: IntGauge,
    pub cache_bytes: IntGauge,
    pub cache_budget_bytes: IntGauge,
    /// Memory mapped for cached tile bodies (their whole pages, and arena pages between them).
    pub cache_mapped_bytes: IntGauge,
    pub cache_outside_bytes: IntGauge,
    pub cache_entries: IntGauge,
    /// Read from the cache's own total at each scrape, with [`Metrics::catch_up`].
    pub cache_evictions: IntCounter,
    pub textures: IntGauge,
    pub store_bytes: IntGauge,
    pub textures_loaded: IntGauge,
    /// Bytes charged against the texture budget: loaded textures and loads in progress.
    pub textures_loaded_bytes: IntGauge,
    pub textures_budget_bytes: IntGauge,
    /// Read from the store's own totals at each scrape, with [`Metrics::catch_up`].
    pub texture_loads: IntCounter,
    pub texture_evictions: IntCounter,
    /// Open connections by the I/O runtime serving them (`runtime` = 0, 1, …).
    pub connections: IntGaugeVec,
    /// The limit on open connections (`--max-connections`).
    pub connections_max: IntGauge,
    /// Connections refused, by the limit that refused them (`limit` = `max-connections`, a 503,
    /// or `max-connections-per-client`, a 429).
    pub connections_refused: IntCounterVec,
    /// Connections with no request in flight closed to admit a new one at the limit.
    pub connections_evicted: IntCounter,
    /// Bytes reserved by response bodies in flight.
    pub inflight_bytes: IntGauge,
    pub inflight_budget_bytes: IntGauge,
    /// Bytes each model's synthesis cache holds (shared by the server's textures), and their budget.
    pub model_cache_bytes: IntGaugeVec,
    pub model_cache_budget_bytes: IntGauge,
    /// The models' own work counters (`vtex_synth::resources::Part::work`), by model and kind.
    model_work: IntCounterVec,
    /// Serialises the counters' catching up with the totals they mirror, so that two scrapes
    /// at once do not both add the same difference.
    catch_up: std::sync::Mutex<()>,
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
            HistogramOpts::new(
                "vtex_http_request_duration_seconds",
                "HTTP request latency by route, to the response headers (a streamed batch ends later)",
            )
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
        let synthesis_seconds = must(HistogramVec::new(
            HistogramOpts::new("vtex_synthesis_seconds", "Time to render one tile or region, by model")
                .buckets(fast.clone()),
            &["model"],
        ));
        let encode_seconds = must(HistogramVec::new(
            HistogramOpts::new("vtex_encode_seconds", "Time to encode one tile or region, by format").buckets(fast),
            &["format"],
        ));
        let batch_seconds = must(HistogramVec::new(
            HistogramOpts::new(
                "vtex_tile_batch_seconds",
                "Tile batches from the request to the end of the body, by outcome: complete, dropped \
                 (the client went away) or timeout",
            )
            .buckets(vec![0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0]),
            &["outcome"],
        ));
        let syntheses_in_flight = must(IntGauge::new("vtex_syntheses_in_flight", "Syntheses running now"));
        let syntheses_stopped = must(IntCounter::new(
            "vtex_syntheses_stopped_total",
            "Renders stopped before their end (every request waiting for them gone, or shutdown)",
        ));
        let syntheses_shed = must(IntCounter::new(
            "vtex_syntheses_shed_total",
            "Misses answered 503 because the synthesis queue was full",
        ));
        let syntheses_queued = must(IntGauge::new("vtex_syntheses_queued", "Misses waiting for a synthesis slot"));
        let cache_bytes = must(IntGauge::new("vtex_tile_cache_bytes", "Bytes held by the tile cache"));
        let cache_budget_bytes = must(IntGauge::new("vtex_tile_cache_budget_bytes", "Byte budget of the tile cache"));
        let cache_mapped_bytes = must(IntGauge::new(
            "vtex_tile_cache_mapped_bytes",
            "Memory mapped for tile bodies (whole pages; huge-page arenas with their free pages)",
        ));
        let cache_outside_bytes = must(IntGauge::new(
            "vtex_tile_cache_outside_bytes",
            "Memory of tile bodies no longer cached that responses still send (charged to the cache's budget)",
        ));
        let cache_entries = must(IntGauge::new("vtex_tile_cache_entries", "Tiles held by the tile cache"));
        let cache_evictions = must(IntCounter::new("vtex_tile_cache_evictions_total", "Tiles evicted from the cache"));
        let textures = must(IntGauge::new("vtex_textures", "Textures in the store (indexed and served)"));
        let store_bytes = must(IntGauge::new("vtex_store_bytes", "Bytes of the stored bundles on disk"));
        let textures_loaded = must(IntGauge::new("vtex_textures_loaded", "Textures loaded in memory"));
        let textures_loaded_bytes = must(IntGauge::new(
            "vtex_textures_loaded_bytes",
            "Bytes loaded textures hold (as their plans state), loads in progress included",
        ));
        let textures_budget_bytes = must(IntGauge::new("vtex_textures_budget_bytes", "Byte budget of loaded textures"));
        let texture_loads = must(IntCounter::new("vtex_texture_loads_total", "Textures loaded, uploads included"));
        let texture_evictions =
            must(IntCounter::new("vtex_texture_evictions_total", "Loaded textures evicted to stay within the budget"));
        let connections = must(IntGaugeVec::new(
            Opts::new("vtex_http_connections", "Open connections by the I/O runtime (thread) serving them"),
            &["runtime"],
        ));
        let connections_max =
            must(IntGauge::new("vtex_http_connections_max", "Open connections served at once (--max-connections)"));
        let connections_refused = must(IntCounterVec::new(
            Opts::new(
                "vtex_http_connections_refused_total",
                "Connections answered and closed at a connection limit: 503 at --max-connections (every \
                 connection with a request in flight), 429 at --max-connections-per-client",
            ),
            &["limit"],
        ));
        let connections_evicted = must(IntCounter::new(
            "vtex_http_connections_evicted_total",
            "Connections with no request in flight (silent, or idle keep-alive) closed to admit a new one at \
             --max-connections",
        ));
        let inflight_bytes = must(IntGauge::new(
            "vtex_inflight_bytes",
            "Bytes reserved by bodies in flight (regions from their render until sent, bundle downloads, \
             batch frames, uploads while read and stored)",
        ));
        let inflight_budget_bytes = must(IntGauge::new(
            "vtex_inflight_budget_bytes",
            "Byte budget of bodies in flight (responses, and uploads while read and stored)",
        ));
        let model_cache_bytes = must(IntGaugeVec::new(
            Opts::new("vtex_model_cache_bytes", "Bytes held by each model's synthesis cache"),
            &["model"],
        ));
        let model_cache_budget_bytes = must(IntGauge::new(
            "vtex_model_cache_budget_bytes",
            "Byte budget of each model's synthesis cache (--synth-cache-mb)",
        ));
        let model_work = must(IntCounterVec::new(
            Opts::new(
                "vtex_model_work_total",
                "Work the models count in their renders, by model and kind (order-independent: every entry \
                 computed, noise included, and pixels requested, whose ratio is the paper's computation ratio; \
                 noise entries, the noise part of the entries computed)",
            ),
            &["model", "kind"],
        ));
        for c in [
            Box::new(requests.clone()) as Box<dyn prometheus::core::Collector>,
            Box::new(request_seconds.clone()),
            Box::new(bytes_out.clone()),
            Box::new(hits_vec.clone()),
            Box::new(misses_vec.clone()),
            Box::new(syntheses.clone()),
            Box::new(synthesis_seconds.clone()),
            Box::new(encode_seconds.clone()),
            Box::new(batch_seconds.clone()),
            Box::new(syntheses_in_flight.clone()),
            Box::new(syntheses_stopped.clone()),
            Box::new(syntheses_shed.clone()),
            Box::new(syntheses_queued.clone()),
            Box::new(cache_bytes.clone()),
            Box::new(cache_budget_bytes.clone()),
            Box::new(cache_mapped_bytes.clone()),
            Box::new(cache_outside_bytes.clone()),
            Box::new(cache_entries.clone()),
            Box::new(cache_evictions.clone()),
            Box::new(textures.clone()),
            Box::new(store_bytes.clone()),
            Box::new(textures_loaded.clone()),
            Box::new(textures_loaded_bytes.clone()),
            Box::new(textures_budget_bytes.clone()),
            Box::new(texture_loads.clone()),
            Box::new(texture_evictions.clone()),
            Box::new(connections.clone()),
            Box::new(connections_max.clone()),
            Box::new(connections_refused.clone()),
            Box::new(connections_evicted.clone()),
            Box::new(inflight_bytes.clone()),
            Box::new(inflight_budget_bytes.clone()),
            Box::new(model_cache_bytes.clone()),
            Box::new(model_cache_budget_bytes.clone()),
            Box::new(model_work.clone()),
        ] {
            must(registry.register(c));
        }
        #[cfg(target_os = "linux")]
        must(registry.register(Box::new(prometheus::process_collector::ProcessCollector::for_self())));
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
            batch_seconds,
            syntheses_in_flight,
            syntheses_stopped,
            syntheses_shed,
            syntheses_queued,
            cache_bytes,
            cache_budget_bytes,
            cache_mapped_bytes,
            cache_outside_bytes,
            cache_entries,
            cache_evictions,
            textures,
            store_bytes,
            textures_loaded,
            textures_loaded_bytes,
            textures_budget_bytes,
            texture_loads,
            texture_evictions,
            connections,
            connections_max,
            connections_refused,
            connections_evicted,
            inflight_bytes,
            inflight_budget_bytes,
            model_cache_bytes,
            model_cache_budget_bytes,
            model_work,
            catch_up: std::sync::Mutex::new(()),
        }
    }

    /// Advances `counter` to `total`, a count kept elsewhere since start: a counter mirrors
    /// it, so that it is exposed as one (`_total`, only ever rising).
    pub fn catch_up(&self, counter: &IntCounter, total: u64) {
        let _serial = self.catch_up.lock().unwrap_or_else(|e| e.into_inner());
        counter.inc_by(total.saturating_sub(counter.get()));
    }

    /// Reads every registered model's cache size and work counters in `resources` into their
    /// metrics.
    pub fn read_models(&self, resources: &Resources) {
        for m in vtex_synth::models::REGISTRY {
            self.model_cache_bytes.with_label_values(&[m.id()]).set(resources.cache_bytes(m.id()) as i64);
        }
        for (model, kind, total) in resources.work() {
            self.catch_up(&self.model_work.with_label_values(&[model, kind]), total);
        }
    }

    /// Counts one finished request: by route (its template, or [`STATIC`]), method and
    /// status; its latency; its body bytes.
    pub fn request_done(&self, route: &str, method: &str, status: &str, seconds: f64, bytes: u64) {
        self.requests.with_label_values(&[route, method, status]).inc();
        self.request_seconds.with_label_values(&[route]).observe(seconds);
        self.bytes_out.inc_by(bytes);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_counted_by_route_method_and_status() {
        let m = Metrics::new();
        let tile = "/api/v1/textures/{id}/tiles/{level}/{x}/{file}";
        m.request_done(tile, "GET", "200", 0.001, 10);
        m.request_done(tile, "GET", "200", 0.001, 10);
        m.request_done(tile, "HEAD", "200", 0.001, 0);
        m.request_done(tile, "GET", "404", 0.001, 5);
        let text = m.render();
        let tiles = format!(r#"route="{tile}""#);
        let line = |method: &str, status: &str| {
            let want = format!(r#"vtex_http_requests_total{{method="{method}",{tiles},status="{status}"}}"#);
            text.lines().find(|l| l.starts_with(&want)).map(|l| l.rsplit(' ').next().unwrap().to_string())
        };
        assert_eq!(line("GET", "200").as_deref(), Some("2"));
        assert_eq!(line("HEAD", "200").as_deref(), Some("1"));
        assert_eq!(line("GET", "404").as_deref(), Some("1"));
        assert_eq!(line("GET", "304"), None, "series never counted are not listed");
        assert!(text.contains(&format!("vtex_http_request_duration_seconds_count{{{tiles}}} 4")));
        assert!(text.contains("vtex_http_response_bytes_total 25"));
    }

    #[test]
    fn counters_catch_up_with_their_totals_once() {
        let m = Metrics::new();
        for total in [5, 5, 7, 7] {
            m.catch_up(&m.cache_evictions, total);
        }
        assert!(m.render().contains("\nvtex_tile_cache_evictions_total 7\n"), "{}", m.render());
    }

    #[test]
    fn every_model_reports_its_cache() {
        let m = Metrics::new();
        m.read_models(&Resources::default());
        let text = m.render();
        for id in vtex_synth::models::ids() {
            assert!(text.contains(&format!(r#"vtex_model_cache_bytes{{model="{id}"}}"#)), "{id}: {text}");
        }
    }
}
