//! The fuzzing loop: mutate an input from the corpus, run it with bounds armed, catch a panic,
//! and on any failure write the input to `fuzz/crashes/<target>-<hash>` and stop.
//!
//! There is no coverage guidance (that needs an instrumented nightly build): the corpus is the
//! project-made seeds plus mutated inputs the parser accepted, so mutations go on from valid
//! inputs as well as from the seeds.

use crate::alloc;
use crate::targets::Target;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Inputs the parser accepted that are kept to mutate further.
const MAX_CORPUS: usize = 256;

/// Where failing inputs are written.
pub fn crash_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("crashes")
}

/// What a run did.
#[derive(Debug, Default)]
pub struct Stats {
    pub seeds: usize,
    pub inputs: u64,
    pub accepted: u64,
    pub elapsed: Duration,
    /// Largest single allocation and largest live-heap growth of any input.
    pub largest_alloc: usize,
    pub peak_live: usize,
}

impl std::fmt::Display for Stats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let secs = self.elapsed.as_secs_f64();
        write!(
            f,
            "{} inputs ({} seeds) in {secs:.1} s ({:.0}/s), {} accepted; largest allocation {} bytes, peak live growth {} bytes",
            self.inputs,
            self.seeds,
            self.inputs as f64 / secs.max(1e-9),
            self.accepted,
            self.largest_alloc,
            self.peak_live
        )
    }
}

/// The input being run, for the reports made from the allocator and the watchdog.
struct Current {
    target: &'static str,
    input: Vec<u8>,
}

static CURRENT: Mutex<Option<Current>> = Mutex::new(None);
/// Milliseconds since [`EPOCH`] at which the current input started; 0 between inputs.
static STARTED_MS: AtomicU64 = AtomicU64::new(0);
static EPOCH: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
static PANIC: Mutex<Option<String>> = Mutex::new(None);

fn now_ms() -> u64 {
    EPOCH.get_or_init(Instant::now).elapsed().as_millis() as u64 + 1
}

/// Writes the failing input, says where, and ends the process with status 1.
fn fail(what: &str) -> ! {
    let current = CURRENT.lock().unwrap_or_else(|e| e.into_inner()).take();
    let Some(Current { target, input }) = current else {
        eprintln!("vtex-fuzz: {what} (outside any input)");
        std::process::exit(1);
    };
    let dir = crash_dir();
    let path = dir.join(format!("{target}-{}", &vtex_synth::bundle::id_of(&input)[..16]));
    let written = std::fs::create_dir_all(&dir).and_then(|_| std::fs::write(&path, &input));
    match written {
        Ok(()) => eprintln!(
            "vtex-fuzz: {target}: {what}\n  input ({} bytes) written to {}\n  replay: cargo run --release -p vtex-fuzz -- {target} --replay {}",
            input.len(),
            path.display(),
            path.display()
        ),
        Err(e) => eprintln!("vtex-fuzz: {target}: {what}; could not write the input to {}: {e}", path.display()),
    }
    std::process::exit(1);
}

/// Runs on the allocating thread, so the backtrace names the allocation's site.
fn on_violation(v: alloc::Violation) {
    // Symbolising the backtrace takes a while: the watchdog must not report a timeout meanwhile.
    STARTED_MS.store(0, Relaxed);
    let site = std::backtrace::Backtrace::force_capture();
    fail(&format!("allocation over the bound: {v}\n{site}"));
}

/// Sets up the failure reports once per process: the allocator's, the panic hook's, and a
/// watchdog that reports an input running past `timeout`.
fn install(timeout: Duration) {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        alloc::on_violation(on_violation);
        std::panic::set_hook(Box::new(|info| {
            let msg = info.payload().downcast_ref::<&str>().map(|s| s.to_string());
            let msg = msg.or_else(|| info.payload().downcast_ref::<String>().cloned()).unwrap_or_default();
            let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
            *PANIC.lock().unwrap_or_else(|e| e.into_inner()) = Some(format!("{msg}{at}"));
        }));
        now_ms();
        std::thread::spawn(move || loop {
            std::thread::sleep(Duration::from_millis(100));
            let started = STARTED_MS.load(Relaxed);
            if started != 0 && now_ms().saturating_sub(started) > timeout.as_millis() as u64 {
                alloc::disarm();
                fail(&format!("one input ran for more than {} s", timeout.as_secs_f64()));
            }
        });
    });
}

/// Runs one input with every check; returns whether the target accepted it, and what it
/// allocated (largest single, peak live growth).
fn run_one(target: &'static dyn Target, input: &[u8]) -> (bool, usize, usize) {
    *CURRENT.lock().unwrap_or_else(|e| e.into_inner()) = Some(Current { target: target.name(), input: input.to_vec() });
    let bounds = target.bounds();
    STARTED_MS.store(now_ms(), Relaxed);
    alloc::arm(bounds.max_alloc, bounds.max_live);
    let outcome = catch_unwind(AssertUnwindSafe(|| target.run(input)));
    let (largest, peak) = alloc::disarm();
    STARTED_MS.store(0, Relaxed);
    match outcome {
        Ok(accepted) => (accepted, largest, peak),
        Err(_) => {
            let msg = PANIC.lock().unwrap_or_else(|e| e.into_inner()).take().unwrap_or_default();
            fail(&format!("panic: {msg}"))
        }
    }
}

/// Fuzzes `target` for `duration` from `seed`; returns at the end, or ends the process on the
/// first failure.
pub fn fuzz(target: &'static dyn Target, duration: Duration, seed: u64) -> Stats {
    install(target.bounds().timeout);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut session = mutatis::Session::new().seed(seed);
    let seeds = target.seeds();
    assert!(!seeds.is_empty(), "{} has no seeds", target.name());
    let mut corpus: Vec<Vec<u8>> = Vec::new();
    let mut stats = Stats { seeds: seeds.len(), ..Stats::default() };
    let start = Instant::now();
    // Every seed once as it is, then mutants: at least one, however slow the seeds were.
    for s in &seeds {
        let (ok, largest, peak) = run_one(target, s);
        stats.note(ok, largest, peak);
    }
    while stats.inputs == seeds.len() as u64 || start.elapsed() < duration {
        let from = if corpus.is_empty() || rng.random_bool(0.5) {
            &seeds[rng.random_range(0..seeds.len())]
        } else {
            &corpus[rng.random_range(0..corpus.len())]
        };
        let mut input = from.clone();
        for _ in 0..rng.random_range(1..=4) {
            target.mutate(&mut rng, &mut session, &mut input);
        }
        let (ok, largest, peak) = run_one(target, &input);
        stats.note(ok, largest, peak);
        if ok {
            if corpus.len() < MAX_CORPUS {
                corpus.push(input);
            } else {
                let i = rng.random_range(0..MAX_CORPUS);
                corpus[i] = input;
            }
        }
    }
    stats.elapsed = start.elapsed();
    stats
}

/// Runs one saved input through `target` with every check (to reproduce a crash file).
pub fn replay(target: &'static dyn Target, input: &[u8]) -> bool {
    install(target.bounds().timeout);
    run_one(target, input).0
}

impl Stats {
    fn note(&mut self, accepted: bool, largest: usize, peak: usize) {
        self.inputs += 1;
        self.accepted += accepted as u64;
        self.largest_alloc = self.largest_alloc.max(largest);
        self.peak_live = self.peak_live.max(peak);
    }
}
