//! A few seconds of every target through the real binary, so CI keeps the harness working and
//! catches what a short run finds; the long runs are `scripts/fuzz-all`. That the harness
//! reports what it finds is `detects.rs`'s job.

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_vtex-fuzz");

fn targets() -> Vec<String> {
    let out = Command::new(BIN).arg("list").output().unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout).unwrap().lines().map(str::to_string).collect()
}

#[test]
fn every_target_runs() {
    let names = targets();
    assert_eq!(names.len(), 7, "{names:?}");
    for name in names {
        let out = Command::new(BIN).args([&name, "--seconds", "1", "--seed", "7"]).output().unwrap();
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(
            out.status.success(),
            "{name} failed its smoke run (replay the input it names with --replay): {stderr}"
        );
        let summary = stdout.lines().last().unwrap_or_default();
        let number = |before: &str| -> u64 {
            summary.split(before).next().and_then(|s| s.rsplit([' ', '(']).next()).unwrap().parse().unwrap()
        };
        let (inputs, seeds) = (number(" inputs"), number(" seeds"));
        assert!(seeds > 0 && inputs > seeds, "{name} ran no mutated input: {summary}");
    }
}
