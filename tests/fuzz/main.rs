//! The fuzz harness (issue 17): seeded mutations of the suite's scene scripts, a synthesised
//! dataset, a trained field and a mined library, each loaded as the tools load them, with
//! the rules: no panic, no abort, no hang, no allocation beyond memory, and nothing accepted
//! that holds a non-finite or inconsistent value (a loader that says "ok" where the next
//! command then fails is a failure too).
//!
//! `cargo test --test fuzz` runs a few thousand cases per format (under a minute on 2
//! cores). The environment sets the rest:
//! - `ASSETFIELD_FUZZ_CASES=N`: cases per format (any number; the default is the CI size);
//! - `ASSETFIELD_FUZZ_SEED=S`: another base seed, for new cases;
//! - `ASSETFIELD_FUZZ_ONLY=FORMAT:CASE`: run that one case here and save its mutated input;
//! - `ASSETFIELD_FUZZ_CASE_SECONDS`, `ASSETFIELD_FUZZ_MEMORY_MB`, `ASSETFIELD_FUZZ_WORKERS`:
//!   the bounds of each case (see [`harness::Settings`]).
//!
//! Arguments after `--` that name formats (`script dataset field library`) run only those; any
//! other filter (as `cargo test NAME` passes to every test binary) runs none.
//!
//! This target has no test harness of its own (`harness = false`): it is its own supervisor
//! and, started with `ASSETFIELD_FUZZ_WORKER` set, its own worker process.

mod formats;
mod harness;
mod mutate;

use assetfield_tests::{assetfield_bin, repo, scene_files, scratch};
use formats::{Format, Seeds};
use std::path::Path;
use std::process::ExitCode;

/// Cases per format in a plain `cargo test`, chosen so the four formats together stay under
/// a minute on the 2-core CI machine (a debug build).
fn default_cases(format: Format) -> u64 {
    match format {
        Format::Script => 4000,
        Format::Dataset => 4000,
        Format::Field => 4000,
        Format::Library => 3000,
        Format::Canary => 8,
    }
}

/// Make the valid inputs: the suite's scripts as they are, a tiny dataset synthesised from
/// one of them, the tiny field and a library mined from the small real field, both shipped
/// with the tests. All are the same bytes on every run of a checkout, so a case number names
/// one mutated input.
fn make_seeds(dir: &Path) -> Seeds {
    let run = |args: &[&str]| {
        let out = std::process::Command::new(assetfield_bin())
            .args(args)
            .current_dir(dir)
            .output()
            .expect("assetfield runs");
        assert!(
            out.status.success(),
            "making a fuzz seed failed: assetfield {args:?}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let plaza = repo().join("scenes/plaza.ron");
    let small = ["--views", "4", "--test-views", "1", "--res", "16", "--aa", "1"];
    run(&[&["synth", plaza.to_str().unwrap(), "--out", "dataset"][..], &small[..]].concat());
    // the library comes from the shipped field, which has objects to mine
    let shipped = repo().join("tests/data/living_room_s128.safetensors");
    run(&["mine", shipped.to_str().unwrap(), "--out", "library"]);
    Seeds {
        scripts: scene_files(),
        dataset: dir.join("dataset"),
        // a field trained for a few steps on such a dataset: small, so thousands of cases
        // run fast; frozen, so that case numbers stay put (tests/data/README.md)
        field: repo().join("tests/data/fuzz_field_s16.safetensors"),
        library: dir.join("library"),
    }
}

fn main() -> ExitCode {
    if let Ok(name) = std::env::var("ASSETFIELD_FUZZ_WORKER") {
        let format = Format::parse(&name).expect("a known format");
        harness::worker(format);
        return ExitCode::SUCCESS;
    }
    mutate::self_check();
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let mut formats: Vec<Format> = Format::ALL.to_vec();
    if !args.is_empty() {
        formats.retain(|f| args.iter().any(|a| a == f.name()));
        if formats.is_empty() {
            println!("fuzz: no format matches {args:?}; nothing run");
            return ExitCode::SUCCESS;
        }
    }
    let settings = harness::Settings::from_env();
    let dir = scratch("fuzz");
    let seeds = make_seeds(&dir);
    if let Ok(only) = std::env::var("ASSETFIELD_FUZZ_ONLY") {
        let (f, c) = only.split_once(':').expect("ASSETFIELD_FUZZ_ONLY=FORMAT:CASE");
        let format = Format::parse(f).expect("a known format");
        harness::reproduce(format, c.parse().expect("a case number"), &seeds, &settings, &dir);
        return ExitCode::SUCCESS;
    }
    harness::canary_check(&seeds, &settings, &dir);
    let cases_env: Option<u64> =
        std::env::var("ASSETFIELD_FUZZ_CASES").ok().and_then(|v| v.trim().parse().ok());
    let mut failed = 0usize;
    for format in formats {
        let cases = cases_env.unwrap_or_else(|| default_cases(format));
        let start = std::time::Instant::now();
        let t = harness::run_format(format, &seeds, cases, &settings, &dir);
        println!(
            "fuzz {:<8} {cases} cases in {:.1} s: {} accepted, {} refused, {} broke a rule",
            format.name(),
            start.elapsed().as_secs_f64(),
            t.accepted,
            t.refused,
            t.failures.len()
        );
        for f in t.failures.iter().take(20) {
            println!(
                "  FAIL {} case {} (rerun: ASSETFIELD_FUZZ_SEED={} ASSETFIELD_FUZZ_ONLY={}:{} cargo test --test fuzz):\n    {}",
                f.format.name(),
                f.case,
                settings.seed,
                f.format.name(),
                f.case,
                f.what.replace('\n', "\n    ")
            );
        }
        if t.failures.len() > 20 {
            println!("  ... and {} more", t.failures.len() - 20);
        }
        failed += t.failures.len();
    }
    let _ = std::fs::remove_dir_all(&dir);
    if failed > 0 {
        println!("fuzz: {failed} cases broke a rule");
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
