//! `/metrics` as Prometheus reads it: the live exposition passes `promtool check metrics`
//! (Prometheus's own parser and linter), counters are typed as counters and named `_total`,
//! and the process's `process_*` family is there with plausible values.

use crate::support::*;
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
