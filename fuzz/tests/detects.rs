//! The harness's failure reports: a panic, one allocation over the bound, live heap over the
//! bound and an input over its time bound each end the run with status 1 and the input written
//! to `fuzz/crashes/`. Each case runs this test binary again as a child that fuzzes a target
//! made to fail that way (the report ends the process).

use rand::rngs::StdRng;
use std::process::Command;
use std::time::Duration;
use vtex_fuzz::alloc::Counting;
use vtex_fuzz::harness;
use vtex_fuzz::targets::{Bounds, Target};

#[global_allocator]
static ALLOC: Counting = Counting;

const BOUND: usize = 1 << 20;

/// Fails once an input holds the byte `!`, in the way its name says.
struct Failing(&'static str);

impl Target for Failing {
    fn name(&self) -> &'static str {
        self.0
    }

    fn bounds(&self) -> Bounds {
        Bounds { max_alloc: BOUND, max_live: BOUND, timeout: Duration::from_millis(500) }
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        vec![b"seed".to_vec()]
    }

    fn mutate(&self, _: &mut StdRng, _: &mut mutatis::Session, input: &mut Vec<u8>) {
        input.push(b'!');
    }

    fn run(&self, input: &[u8]) -> bool {
        if !input.contains(&b'!') {
            // Within the bounds: many allocations under the single bound, all freed.
            let small: Vec<Vec<u8>> = (0..64).map(|_| vec![1u8; BOUND / 128]).collect();
            return small.len() == 64;
        }
        match self.0 {
            "selftest-panic" => panic!("deliberate"),
            "selftest-alloc" => !std::hint::black_box(vec![0u8; BOUND + 1]).is_empty(),
            "selftest-live" => {
                let held: Vec<Vec<u8>> = (0..4).map(|_| vec![1u8; BOUND / 2]).collect();
                std::hint::black_box(held).len() == 4
            }
            _ => {
                std::thread::sleep(Duration::from_secs(30));
                true
            }
        }
    }
}

static CASES: [Failing; 4] =
    [Failing("selftest-panic"), Failing("selftest-alloc"), Failing("selftest-live"), Failing("selftest-slow")];

/// The child: fuzzes the target named by `VTEX_FUZZ_SELFTEST`; in a normal run, does nothing.
#[test]
fn child() {
    if let Ok(name) = std::env::var("VTEX_FUZZ_SELFTEST") {
        let target = CASES.iter().find(|t| t.0 == name).unwrap();
        harness::fuzz(target, Duration::from_secs(20), 1);
        unreachable!("{name} was not reported");
    }
}

#[test]
fn each_failure_is_reported_with_its_input() {
    for (case, expect) in [
        ("selftest-panic", "panic: deliberate"),
        ("selftest-alloc", "one allocation of 1048577 bytes; bound 1048576"),
        ("selftest-live", "live heap grew by"),
        ("selftest-slow", "one input ran for more than 0.5 s"),
    ] {
        let out = Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "child", "--nocapture"])
            .env("VTEX_FUZZ_SELFTEST", case)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{case}: {stderr}");
        assert!(stderr.contains(&format!("vtex-fuzz: {case}: ")) && stderr.contains(expect), "{case}: {stderr}");
        let path = stderr.split("written to ").nth(1).and_then(|s| s.lines().next()).expect(&stderr);
        assert!(path.contains(&format!("crashes/{case}-")), "{path}");
        let input = std::fs::read(path).unwrap();
        assert!(input.starts_with(b"seed") && input.contains(&b'!'), "{case}: the failing input is the one written");
        std::fs::remove_file(path).unwrap();
    }
}
