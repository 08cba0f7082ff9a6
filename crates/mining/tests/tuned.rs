//! The list of tuned numbers ([`assetfield_mining::tuned`]) is the whole truth: every number
//! of the mining options is listed or said here not to be tuned, every numeric literal of
//! the mining source is marked `// tuned: NAME` (an entry of the list) or `// fixed: REASON`,
//! and the list stays within its budget.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use assetfield_mining::pipeline::MineOptions;
use assetfield_mining::tuned::{self, BUDGET};

/// Numbers of [`MineOptions`] that are not tuned, and why (serialised paths).
const NOT_TUNED_OPTIONS: [(&str, &str); 12] = [
    ("detect.k", "a choice: the paper's two first-round clusters"),
    ("detect.seed", "a seed"),
    ("group.seed", "a seed"),
    ("group.shape_weight", "a switch: 1 adds the shape term as it is, 0 drops it"),
    ("group.profile_weight", "a switch: 1 adds the profile term as it is, 0 drops it"),
    ("group.max_samples", "a sample budget: twice as many mined the basis the same"),
    ("pose.margin", "the field's blur (detect.blur_levels) across"),
    ("pose.yaw.period_deg", "a full turn: no symmetry is known"),
    ("pose.yaw.max_offset", "half the field's blur (detect.blur_levels) across"),
    ("pose.yaw.tol_deg", "a precision: a fifth of it mined the basis the same"),
    ("iou", "the evaluation's standard IoU, not mining"),
    ("own_patch_residual", "a choice: every instance keeps its own patch"),
];

/// Source files of the crate whose numbers decide nothing of mining.
const NOT_MINING: [&str; 9] = [
    "metrics.rs",      // the evaluation against a ground truth
    "picture.rs",      // drawing the pictures
    "merge.rs",        // merging libraries
    "error.rs",        // messages
    "image.rs",        // containers
    "rng.rs",          // the generator's mixing constants
    "tuned.rs",        // the list itself
    "detect/tests.rs", // tests
    "test_support.rs", // tests
];

fn numbers(v: &serde_json::Value, path: &str, out: &mut BTreeMap<String, f64>) {
    match v {
        serde_json::Value::Number(n) => {
            out.insert(path.to_string(), n.as_f64().unwrap_or(f64::NAN));
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                numbers(x, &format!("{path}[{i}]"), out);
            }
        }
        serde_json::Value::Object(o) => {
            for (k, x) in o {
                let p = if path.is_empty() { k.clone() } else { format!("{path}.{k}") };
                numbers(x, &p, out);
            }
        }
        _ => {}
    }
}

#[test]
fn mining_has_at_most_its_budget_of_tuned_numbers_and_each_says_why() {
    let list = tuned::tuned_defaults();
    assert_eq!(tuned::count_tuned(), list.len());
    assert!(list.len() <= BUDGET, "{} tuned numbers, the budget is {BUDGET}", list.len());
    let mut names = BTreeSet::new();
    for t in &list {
        assert!(names.insert(t.name), "{} is listed twice", t.name);
        assert!(t.value.is_finite(), "{}", t.name);
        assert!(!t.unit.is_empty() && t.why.len() > 20, "{} needs a unit and a reason", t.name);
    }
}

#[test]
fn every_number_of_the_options_is_listed_or_said_not_to_be_tuned() {
    let mut leaves = BTreeMap::new();
    numbers(&serde_json::to_value(MineOptions::default()).unwrap(), "", &mut leaves);
    let listed: BTreeMap<&str, f64> =
        tuned::tuned_defaults().iter().filter(|t| t.option).map(|t| (t.name, t.value)).collect();
    let not_tuned: BTreeSet<&str> = NOT_TUNED_OPTIONS.iter().map(|(n, _)| *n).collect();
    for (path, value) in &leaves {
        match (listed.get(path.as_str()), not_tuned.contains(path.as_str())) {
            (Some(v), false) => {
                assert!((v - value).abs() <= 1e-6 * value.abs().max(1.0), "{path}: {v} vs {value}")
            }
            (None, true) => {}
            (Some(_), true) => panic!("{path} is both tuned and not"),
            (None, false) => panic!(
                "{path} = {value} is a number of the mining options that is neither in \
                 assetfield_mining::tuned nor in NOT_TUNED_OPTIONS"
            ),
        }
    }
    for name in listed.keys().chain(not_tuned.iter()) {
        assert!(leaves.contains_key(*name), "{name} is no number of MineOptions");
    }
}

fn sources(dir: &Path, root: &Path, out: &mut Vec<(String, PathBuf)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            sources(&p, root, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
            out.push((rel, p));
        }
    }
}

/// A line without its string and char literals, split into code and comment.
fn code_and_comment(line: &str) -> (String, String) {
    let chars: Vec<char> = line.chars().collect();
    let (mut code, mut i) = (String::new(), 0);
    while i < chars.len() {
        let c = chars[i];
        if c == '"' {
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                i += if chars[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            code.push_str("\"\"");
            continue;
        }
        if c == '\'' {
            // a char literal ('x' or '\n'); otherwise a lifetime
            if chars.get(i + 1) == Some(&'\\') {
                i += 2;
                while i < chars.len() && chars[i] != '\'' {
                    i += 1;
                }
                i += 1;
                code.push_str("' '");
                continue;
            }
            if chars.get(i + 2) == Some(&'\'') {
                i += 3;
                code.push_str("' '");
                continue;
            }
        }
        if c == '/' && chars.get(i + 1) == Some(&'/') {
            return (code, chars[i + 2..].iter().collect());
        }
        code.push(c);
        i += 1;
    }
    (code, String::new())
}

/// The numeric literals of a line of code that must be marked: every one but 0, 1, 2 and
/// 0.5, numerical guards of 1e-6 and below, array lengths (`; N]`) and indices (`[N]`).
fn marked_literals(code: &str) -> Vec<String> {
    let chars: Vec<char> = code.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let prev = if i > 0 { chars[i - 1] } else { ' ' };
        if !c.is_ascii_digit() || prev.is_alphanumeric() || prev == '_' || prev == '.' {
            i += 1;
            continue;
        }
        let start = i;
        if c == '0' && matches!(chars.get(i + 1), Some('x' | 'b' | 'o')) {
            i += 2;
            while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push(chars[start..i].iter().collect());
            continue;
        }
        while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '_') {
            i += 1;
        }
        if chars.get(i) == Some(&'.') && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit()) {
            i += 1;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '_') {
                i += 1;
            }
        } else if chars.get(i) == Some(&'.')
            && !chars.get(i + 1).is_some_and(|d| *d == '.' || d.is_alphabetic())
        {
            i += 1; // `1.`
        }
        let mut exponent = None;
        if matches!(chars.get(i), Some('e' | 'E'))
            && chars
                .get(i + 1)
                .is_some_and(|d| d.is_ascii_digit() || (*d == '-' && chars.get(i + 2).is_some()))
        {
            i += 1;
            let neg = chars.get(i) == Some(&'-');
            if neg {
                i += 1;
            }
            let e0 = i;
            while i < chars.len() && chars[i].is_ascii_digit() {
                i += 1;
            }
            let e: i32 = chars[e0..i].iter().collect::<String>().parse().unwrap_or(0);
            exponent = Some(if neg { -e } else { e });
        }
        let text: String = chars[start..i].iter().filter(|&&d| d != '_').collect();
        // the type suffix
        while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_') {
            i += 1;
        }
        let before = chars[..start].iter().rev().find(|d| !d.is_whitespace()).copied();
        let after = chars[i..].iter().find(|d| !d.is_whitespace()).copied();
        let shape = matches!((before, after), (Some('[' | ';'), Some(']')));
        let guard = exponent.is_some_and(|e| e <= -6);
        let trivial =
            matches!(text.parse::<f64>(), Ok(v) if v == 0.0 || v == 1.0 || v == 2.0 || v == 0.5);
        if !(shape || guard || trivial) {
            out.push(text);
        }
    }
    out
}

fn numeric_const(code: &str) -> bool {
    let Some(at) = code.find("const ") else { return false };
    let rest = &code[at..];
    let Some(colon) = rest.find(':') else { return false };
    let ty = rest[colon + 1..].trim_start();
    ["f32", "f64", "usize", "u64", "u32", "i32", "[usize", "[f32"].iter().any(|t| ty.starts_with(t))
}

fn marker(comment: &str) -> Option<(&'static str, String)> {
    let c = comment.trim_start();
    if let Some(name) = c.strip_prefix("tuned:") {
        let name = name.split_whitespace().next().unwrap_or("").to_string();
        Some(("tuned", name))
    } else if let Some(why) = c.strip_prefix("fixed:") {
        Some(("fixed", why.trim().to_string()))
    } else {
        None
    }
}

#[test]
fn every_number_in_the_mining_source_is_marked_tuned_or_fixed() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&root, &root, &mut files);
    assert!(files.len() > 20, "found only {} sources under {}", files.len(), root.display());
    let mut unmarked = Vec::new();
    let mut names: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (rel, path) in files.iter().filter(|(rel, _)| !NOT_MINING.contains(&rel.as_str())) {
        let text = std::fs::read_to_string(path).unwrap();
        let mut previous: Option<(&'static str, String)> = None;
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("#[cfg(test)]") {
                break;
            }
            let t = line.trim_start();
            if t.starts_with("///") || t.starts_with("//!") {
                previous = None;
                continue;
            }
            let (code, comment) = code_and_comment(line);
            let own = marker(&comment);
            if let Some(("tuned", name)) = &own {
                names.entry(name.clone()).or_default().push(format!("{rel}:{}", n + 1));
            }
            if code.trim().is_empty() {
                previous = own;
                continue;
            }
            let literals = marked_literals(&code);
            let needs = !literals.is_empty() || numeric_const(&code);
            if needs && own.is_none() && previous.is_none() {
                unmarked.push(format!("{rel}:{}: {literals:?} in `{}`", n + 1, code.trim()));
            }
            if let (Some(("fixed", why)), true) = (&own, needs) {
                assert!(!why.is_empty(), "{rel}:{}: `// fixed:` needs a reason", n + 1);
            }
            previous = None;
        }
    }
    assert!(
        unmarked.is_empty(),
        "numbers of the mining source with neither `// tuned: NAME` nor `// fixed: REASON` \
         (a tuned number joins assetfield_mining::tuned):\n{}",
        unmarked.join("\n")
    );
    let listed: BTreeSet<String> =
        tuned::tuned_defaults().iter().map(|t| t.name.to_string()).collect();
    for (name, at) in &names {
        assert!(listed.contains(name), "`// tuned: {name}` at {at:?} names no entry of the list");
        assert_eq!(at.len(), 1, "`// tuned: {name}` marks {at:?}: one definition each");
    }
    for name in &listed {
        assert!(names.contains_key(name), "{name} is listed but marked nowhere in the source");
    }
}

#[test]
fn the_literal_scanner_finds_what_it_should() {
    assert_eq!(marked_literals("let a = 3 * b + 0.25;"), vec!["3", "0.25"]);
    assert!(marked_literals("let x = v[3] + w.0 + 1e-9 + 2.0 * 0.5f32.powi(2);").is_empty());
    assert!(marked_literals("fn f(a: [f32; 4]) -> u8 { 1 }").is_empty());
    assert_eq!(marked_literals("for t in 1..=8 {"), vec!["8"]);
    assert_eq!(marked_literals("let n = 40_000usize;"), vec!["40000"]);
    assert_eq!(code_and_comment("let s = \"// no\"; // yes").1, " yes");
    assert!(numeric_const("pub const X: f32 = 0.5;"));
    assert!(!numeric_const("pub const NAME: &str = \"a\";"));
}
