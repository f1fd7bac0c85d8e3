//! `/metrics` as Prometheus reads it: the live exposition passes `promtool check metrics`
//! (Prometheus's own parser and linter), counters are typed as counters and named `_total`,
//! and the process's `process_*` family is there with plausible values.

mod common;
use common::*;
use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

/// `promtool`: the copy `scripts/test` extracts from Debian's `prometheus` package, else one
/// on the `PATH`.
fn promtool() -> Option<PathBuf> {
    let extracted = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/promtool/usr/bin/promtool");
    if extracted.is_file() {
        return Some(extracted);
    }
    let on_path = Command::new("promtool").arg("--version").output().is_ok_and(|o| o.status.success());
    on_path.then(|| PathBuf::from("promtool"))
}

/// The exposition of a server that has served an upload, tiles (hits and misses) and an
/// error: most series carry values.
async fn busy_exposition(s: &Server) -> String {
    let c = client();
    let id = put(&c, s, &mosaic(64, 16, 1)).await;
    for (x, y) in [(0, 0), (1, 0), (0, 0)] {
        assert_eq!(get_bytes(&c, &s.tile_url(&id, 0, x, y, "png")).await.0, 200);
    }
    assert_eq!(get_bytes(&c, &s.url("/api/v1/textures/nope")).await.0, 400);
    let r = c.get(s.url("/metrics")).send().await.unwrap();
    assert_eq!(r.headers()["content-type"], "text/plain; version=0.0.4");
    r.text().await.unwrap()
}

/// `(name, type)` of every family, from its `# TYPE` line.
fn families(text: &str) -> Vec<(&str, &str)> {
    text.lines().filter_map(|l| l.strip_prefix("# TYPE ")?.split_once(' ')).collect()
}

#[tokio::test]
async fn the_exposition_passes_promtool() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let text = busy_exposition(&s).await;
    let Some(promtool) = promtool() else {
        assert!(std::env::var_os("CI").is_none(), "CI must lint: scripts/test extracts target/promtool");
        eprintln!("promtool not found (scripts/test extracts it): /metrics NOT linted by promtool");
        return;
    };
    let mut child = Command::new(promtool)
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(text.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    let said = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success() && said.trim().is_empty(), "promtool check metrics:\n{said}\n{text}");
}

/// A family is a counter exactly when its name ends in `_total`; the counts the cache and the
/// store keep are counters.
#[tokio::test]
async fn counters_are_counters() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let text = busy_exposition(&s).await;
    let families = families(&text);
    for (name, kind) in &families {
        assert_eq!(name.ends_with("_total"), *kind == "counter", "{name} is a {kind}");
    }
    for counter in ["vtex_tile_cache_evictions_total", "vtex_texture_loads_total", "vtex_texture_evictions_total"] {
        assert!(families.contains(&(counter, "counter")), "{counter}:\n{text}");
    }
    assert_eq!(metric(&text, "vtex_texture_loads_total", &[]), 1.0, "the upload loaded its texture");
}

/// Memory, CPU, descriptors and start time of the server's process (Linux: read from /proc).
#[cfg(target_os = "linux")]
#[tokio::test]
async fn process_metrics_describe_the_server() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let text = busy_exposition(&s).await;
    let families = families(&text);
    for (name, kind) in [
        ("process_resident_memory_bytes", "gauge"),
        ("process_cpu_seconds_total", "counter"),
        ("process_open_fds", "gauge"),
        ("process_max_fds", "gauge"),
        ("process_start_time_seconds", "gauge"),
    ] {
        assert!(families.contains(&(name, kind)), "{name} {kind}:\n{text}");
    }
    let value = |name| metric(&text, name, &[]);
    let status = std::fs::read_to_string(format!("/proc/{}/status", s.child.id())).unwrap();
    let rss_kib: f64 =
        status.lines().find_map(|l| l.strip_prefix("VmRSS:")).unwrap().trim().trim_end_matches(" kB").parse().unwrap();
    let rss = value("process_resident_memory_bytes");
    assert!(rss > 1e6 && (rss / (rss_kib * 1024.0) - 1.0).abs() < 0.5, "RSS {rss} against /proc's {rss_kib} KiB");
    let (open, max) = (value("process_open_fds"), value("process_max_fds"));
    let fds = std::fs::read_dir(format!("/proc/{}/fd", s.child.id())).unwrap().count() as f64;
    assert!(open >= 3.0 && open <= max && (open - fds).abs() <= 8.0, "open {open} (/proc: {fds}), max {max}");
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_secs_f64();
    let started = value("process_start_time_seconds");
    assert!(started <= now + 1.0 && started > now - 300.0, "started at {started}, now {now}");
}
