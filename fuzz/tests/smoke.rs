//! A few seconds of every target through the real binary, so CI keeps the harness working.
//! Finding a failing input is the long runs' job (`scripts/fuzz-all`); here a target must
//! either finish clean or report its finding the harness's way: the input written where the
//! message says, and replaying it fails the same way.

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
        if out.status.success() {
            let summary = stdout.lines().last().unwrap_or_default();
            let number = |before: &str| -> u64 {
                summary.split(before).next().and_then(|s| s.rsplit([' ', '(']).next()).unwrap().parse().unwrap()
            };
            let (inputs, seeds) = (number(" inputs"), number(" seeds"));
            assert!(seeds > 0 && inputs > seeds, "{name} ran no mutated input: {summary}");
            continue;
        }
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        let path = stderr.split("written to ").nth(1).and_then(|s| s.lines().next()).unwrap_or_else(|| {
            panic!("{name} failed without writing its input: {stderr}");
        });
        let reason = stderr.lines().next().unwrap();
        eprintln!("FINDING (not a harness failure) {reason}: {path}");
        let again = Command::new(BIN).args([name.as_str(), "--replay", path]).output().unwrap();
        let again_err = String::from_utf8_lossy(&again.stderr);
        assert_eq!(again.status.code(), Some(1), "{name}: replaying {path} did not fail: {again_err}");
        let kind = |s: &str| s.split(": ").nth(2).map(|k| k.split(' ').next().unwrap_or_default().to_string());
        assert_eq!(kind(reason), kind(again_err.lines().next().unwrap()), "{name}: {reason} / {again_err}");
    }
}
