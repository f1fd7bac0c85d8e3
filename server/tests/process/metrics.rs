//! The process metrics of `/metrics` describe the real server process.

use crate::support::*;

/// Memory, CPU, descriptors and start time of the server's process (Linux: read from /proc).
#[cfg(target_os = "linux")]
#[tokio::test]
async fn process_metrics_describe_the_server() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
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
    let status = std::fs::read_to_string(format!("/proc/{}/status", s.pid())).unwrap();
    let rss_kib: f64 =
        status.lines().find_map(|l| l.strip_prefix("VmRSS:")).unwrap().trim().trim_end_matches(" kB").parse().unwrap();
    let rss = value("process_resident_memory_bytes");
    assert!(rss > 1e6 && (rss / (rss_kib * 1024.0) - 1.0).abs() < 0.5, "RSS {rss} against /proc's {rss_kib} KiB");
    let (open, max) = (value("process_open_fds"), value("process_max_fds"));
    let fds = std::fs::read_dir(format!("/proc/{}/fd", s.pid())).unwrap().count() as f64;
    assert!(open >= 3.0 && open <= max && (open - fds).abs() <= 8.0, "open {open} (/proc: {fds}), max {max}");
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_secs_f64();
    let started = value("process_start_time_seconds");
    assert!(started <= now + 1.0 && started > now - 300.0, "started at {started}, now {now}");
}
