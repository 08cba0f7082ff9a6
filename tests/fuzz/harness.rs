//! The supervisor: cases run in worker processes (this same executable, in worker mode) under
//! an address-space limit, a time limit per case and a panic catcher, so that a panic, an
//! abort, a hang or an allocation too large for memory is reported with its case instead of
//! taking the test run down. A worker that dies or hangs is replaced and the run goes on
//! from the next case.

use crate::formats::{Case, Format, Seeds, Verdict, Workspace, run_case};
use crate::mutate::{Rng, case_seed};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Limits and sizes of a run; every field can be set from the environment.
#[derive(Debug, Clone)]
pub struct Settings {
    /// `ASSETFIELD_FUZZ_SEED`: the base seed (default fixed, so CI runs the same cases).
    pub seed: u64,
    /// `ASSETFIELD_FUZZ_CASE_SECONDS`: a case that runs longer is a hang (default 20 s: the
    /// slowest honest case, a field rendered in a debug build, takes well under 1 s).
    pub case_seconds: f64,
    /// `ASSETFIELD_FUZZ_MEMORY_MB`: the workers' address-space limit (default 3072 MiB: the
    /// inputs need tens of MiB; an allocation sized by a hostile header fails there and is
    /// reported instead of swapping the machine).
    pub memory_mb: u64,
    /// `ASSETFIELD_FUZZ_WORKERS`: worker processes per format (default 2, the CI cores).
    pub workers: usize,
}

fn env_or<T: std::str::FromStr>(key: &str, default: T) -> T {
    std::env::var(key).ok().and_then(|v| v.trim().parse().ok()).unwrap_or(default)
}

impl Settings {
    pub fn from_env() -> Self {
        Settings {
            seed: env_or("ASSETFIELD_FUZZ_SEED", 0x5eed_2026),
            case_seconds: env_or("ASSETFIELD_FUZZ_CASE_SECONDS", 20.0),
            memory_mb: env_or("ASSETFIELD_FUZZ_MEMORY_MB", 3072),
            workers: env_or("ASSETFIELD_FUZZ_WORKERS", 2usize).max(1),
        }
    }
}

/// A broken rule, with what it takes to reproduce it.
#[derive(Debug, Clone)]
pub struct Failure {
    pub format: Format,
    pub case: u64,
    pub what: String,
}

/// Counts of one format's run.
#[derive(Debug, Default, Clone)]
pub struct Tally {
    pub accepted: u64,
    pub refused: u64,
    pub failures: Vec<Failure>,
}

/// The seeds as one environment value (paths joined by newlines; the scripts last).
fn encode_seeds(s: &Seeds) -> String {
    let mut v = vec![s.dataset.clone(), s.field.clone(), s.library.clone()];
    v.extend(s.scripts.iter().cloned());
    v.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join("\n")
}

fn decode_seeds(s: &str) -> Seeds {
    let mut it = s.lines().map(PathBuf::from);
    let dataset = it.next().expect("seed dataset");
    let field = it.next().expect("seed field");
    let library = it.next().expect("seed library");
    Seeds { scripts: it.collect(), dataset, field, library }
}

/// Run cases `range` of `format` in worker processes; returns the tally.
pub fn run_format(
    format: Format,
    seeds: &Seeds,
    cases: u64,
    settings: &Settings,
    scratch: &std::path::Path,
) -> Tally {
    let workers = (settings.workers as u64).min(cases.max(1));
    let per = cases.div_ceil(workers);
    let handles: Vec<_> = (0..workers)
        .map(|w| {
            let (first, end) = (w * per, ((w + 1) * per).min(cases));
            let seeds = seeds.clone();
            let settings = settings.clone();
            let ws = scratch.join(format!("{}-{w}", format.name()));
            std::thread::spawn(move || supervise(format, &seeds, first, end, &settings, ws))
        })
        .collect();
    let mut tally = Tally::default();
    for h in handles {
        let t = h.join().expect("supervisor thread");
        tally.accepted += t.accepted;
        tally.refused += t.refused;
        tally.failures.extend(t.failures);
    }
    tally.failures.sort_by_key(|f| f.case);
    tally
}

enum Line {
    Out(String),
    Closed,
}

fn spawn_worker(
    format: Format,
    seeds: &Seeds,
    first: u64,
    end: u64,
    settings: &Settings,
    ws: &std::path::Path,
) -> std::io::Result<Child> {
    let exe = std::env::current_exe()?;
    // the address-space limit comes from the shell (no unsafe code in this workspace)
    Command::new("sh")
        .arg("-c")
        .arg("ulimit -v \"$0\" && exec \"$@\"")
        .arg((settings.memory_mb * 1024).to_string())
        .arg(exe)
        .env("ASSETFIELD_FUZZ_WORKER", format.name())
        .env("ASSETFIELD_FUZZ_RANGE", format!("{first}..{end}"))
        .env("ASSETFIELD_FUZZ_SEED", settings.seed.to_string())
        .env("ASSETFIELD_FUZZ_SEEDS", encode_seeds(seeds))
        .env("ASSETFIELD_FUZZ_WS", ws)
        // the first line of an abort is its message; a backtrace would push it out of the tail
        .env("RUST_BACKTRACE", "0")
        // one thread per worker: the workers already use the cores
        .env("RAYON_NUM_THREADS", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
}

/// Keep the last `n` bytes of a stream.
fn tail_of(mut r: impl Read + Send + 'static, n: usize) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        let mut chunk = [0u8; 4096];
        while let Ok(k) = r.read(&mut chunk) {
            if k == 0 {
                break;
            }
            buf.extend_from_slice(&chunk[..k]);
            if buf.len() > 4 * n {
                buf.drain(..buf.len() - n);
            }
        }
        let start = buf.len().saturating_sub(n);
        String::from_utf8_lossy(&buf[start..]).into_owned()
    })
}

fn supervise(
    format: Format,
    seeds: &Seeds,
    first: u64,
    end: u64,
    settings: &Settings,
    ws: PathBuf,
) -> Tally {
    let mut tally = Tally::default();
    let mut next = first;
    let limit = Duration::from_secs_f64(settings.case_seconds);
    while next < end {
        let mut child = match spawn_worker(format, seeds, next, end, settings, &ws) {
            Ok(c) => c,
            Err(e) => {
                tally.failures.push(Failure {
                    format,
                    case: next,
                    what: format!("cannot start a worker: {e}"),
                });
                return tally;
            }
        };
        let stdout = child.stdout.take().expect("piped stdout");
        let stderr = tail_of(child.stderr.take().expect("piped stderr"), 2000);
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(Line::Out(line)).is_err() {
                    return;
                }
            }
            let _ = tx.send(Line::Closed);
        });
        let mut current: Option<u64> = None;
        let mut started = Instant::now();
        loop {
            let wait = match current {
                Some(_) => limit.saturating_sub(started.elapsed()),
                None => limit,
            };
            match rx.recv_timeout(wait) {
                Ok(Line::Out(l)) => {
                    let mut parts = l.splitn(4, ' ');
                    if parts.next() != Some("FUZZ") {
                        continue;
                    }
                    let kind = parts.next().unwrap_or("");
                    let case: u64 = parts.next().and_then(|c| c.parse().ok()).unwrap_or(next);
                    let rest = parts.next().unwrap_or("");
                    match kind {
                        "start" => {
                            current = Some(case);
                            started = Instant::now();
                        }
                        "accepted" => tally.accepted += 1,
                        "refused" => tally.refused += 1,
                        "fail" => tally.failures.push(Failure {
                            format,
                            case,
                            what: rest.replace("\\n", "\n"),
                        }),
                        _ => {}
                    }
                    if kind != "start" {
                        current = None;
                        next = case + 1;
                    }
                }
                Ok(Line::Closed) => {
                    let status = child.wait().ok();
                    let err = stderr.join().unwrap_or_default();
                    if let Some(case) = current {
                        tally.failures.push(Failure {
                            format,
                            case,
                            what: format!(
                                "the process died ({}); its last words:\n{}",
                                status.map_or("no status".into(), |s| s.to_string()),
                                err.trim()
                            ),
                        });
                        next = case + 1;
                    } else if next < end {
                        // died between cases: report it once and stop this range
                        tally.failures.push(Failure {
                            format,
                            case: next,
                            what: format!("the worker stopped before case {next}: {}", err.trim()),
                        });
                        return tally;
                    }
                    break;
                }
                Err(_) => {
                    let case = current.unwrap_or(next);
                    let _ = child.kill();
                    let _ = child.wait();
                    tally.failures.push(Failure {
                        format,
                        case,
                        what: format!("no answer within {:.0} s (a hang)", settings.case_seconds),
                    });
                    next = case + 1;
                    break;
                }
            }
        }
    }
    tally
}

/// The message of the last panic of this process, caught by the worker's hook.
static LAST_PANIC: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// Worker mode: run the cases the environment names, one line per case on stdout.
pub fn worker(format: Format) {
    let range = std::env::var("ASSETFIELD_FUZZ_RANGE").expect("ASSETFIELD_FUZZ_RANGE");
    let (a, b) = range.split_once("..").expect("FIRST..END");
    let (first, end): (u64, u64) = (a.parse().expect("first"), b.parse().expect("end"));
    let seed: u64 = std::env::var("ASSETFIELD_FUZZ_SEED").expect("seed").parse().expect("seed");
    let seeds = decode_seeds(&std::env::var("ASSETFIELD_FUZZ_SEEDS").expect("seeds"));
    let ws =
        Workspace::new(&seeds, PathBuf::from(std::env::var_os("ASSETFIELD_FUZZ_WS").expect("ws")))
            .expect("worker workspace");
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| info.payload().downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        let at = info.location().map(|l| format!(" at {l}")).unwrap_or_default();
        *LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()) = Some(format!("{msg}{at}"));
    }));
    let stdout = std::io::stdout();
    for case in first..end {
        {
            let mut o = stdout.lock();
            let _ = writeln!(o, "FUZZ start {case}");
            let _ = o.flush();
        }
        let mut rng = Rng::new(case_seed(seed, format.name(), case));
        let mut c = Case::default();
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run_case(format, case, &seeds, &ws, &mut rng, &mut c)
        }));
        let line = match outcome {
            Ok(Ok(Verdict::Accepted)) => format!("FUZZ accepted {case}"),
            Ok(Ok(Verdict::Refused(_))) => format!("FUZZ refused {case}"),
            Ok(Err(rule)) => format!("FUZZ fail {case} {}", report(&c, &rule)),
            Err(_) => {
                let msg = LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()).take();
                format!(
                    "FUZZ fail {case} {}",
                    report(&c, &format!("panic: {}", msg.unwrap_or_default()))
                )
            }
        };
        let mut o = stdout.lock();
        let _ = writeln!(o, "{line}");
        let _ = o.flush();
    }
}

fn report(c: &Case, what: &str) -> String {
    format!("{what} [input {}; mutations: {}]", c.input, c.mutations.join("; "))
        .replace('\n', "\\n")
}

/// Run one case in this process and say what it did (`ASSETFIELD_FUZZ_ONLY=FORMAT:CASE`); the
/// mutated input is left in the workspace (and, for scripts, printed) to look at.
pub fn reproduce(
    format: Format,
    case: u64,
    seeds: &Seeds,
    settings: &Settings,
    scratch: &std::path::Path,
) {
    let ws = Workspace::new(seeds, scratch.join("reproduce")).expect("workspace");
    let mut rng = Rng::new(case_seed(settings.seed, format.name(), case));
    let mut c = Case::default();
    let outcome = run_case(format, case, seeds, &ws, &mut rng, &mut c);
    println!("{} case {case}: input {}", format.name(), c.input);
    for m in &c.mutations {
        println!("  mutation: {m}");
    }
    println!("  outcome: {outcome:?}");
    let ext = std::path::Path::new(&c.input).extension().map(|e| e.to_string_lossy().into_owned());
    let saved = ws.dir.join(format!("case-{case}.{}", ext.unwrap_or_else(|| "bin".into())));
    match std::fs::write(&saved, &c.mutated) {
        Ok(()) => println!("  the mutated input: {}", saved.display()),
        Err(e) => println!("  cannot save the mutated input to {}: {e}", saved.display()),
    }
}

/// Check the supervisor itself on the canary: each kind of failure (panic, abort, hang,
/// allocation beyond the limit, broken rule) must be reported on its case, and nothing else.
/// Panics (failing the run) when one goes unnoticed.
pub fn canary_check(seeds: &Seeds, settings: &Settings, scratch: &std::path::Path) {
    let quick = Settings { case_seconds: 2.0, workers: 1, ..settings.clone() };
    let t = run_format(Format::Canary, seeds, 8, &quick, scratch);
    let failed: Vec<u64> = t.failures.iter().map(|f| f.case).collect();
    let says = |case: u64, needle: &str| {
        t.failures.iter().any(|f| f.case == case && f.what.contains(needle))
    };
    assert!(
        failed == [0, 1, 2, 3, 4]
            && says(0, "panic: the canary panics")
            && says(1, "SIGABRT")
            && says(2, "a hang")
            && says(3, "memory allocation")
            && says(4, "breaks the oracle")
            && t.accepted == 3,
        "the fuzz supervisor missed a failure of its canary: {t:#?}"
    );
    println!(
        "fuzz canary: its panic, abort, hang, allocation beyond the limit and broken rule were each caught"
    );
}
