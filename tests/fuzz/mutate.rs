//! Seeded mutations of text (RON, JSON) and of safetensors files: the same seed always gives
//! the same mutated bytes, so a failing case is reproduced from its format, seed and number.

/// The layout language's seeded generator (SplitMix64: the same on every machine), with the
/// draws a mutator needs.
#[derive(Debug, Clone)]
pub struct Rng(assetfield_layout::rng::Rng);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(assetfield_layout::rng::Rng::new(seed))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `0..n` (`n` > 0).
    pub fn below(&mut self, n: usize) -> usize {
        self.0.below(n)
    }

    pub fn chance(&mut self, p: f64) -> bool {
        (self.0.f32() as f64) < p
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// The seed of case `case` of `format` under the run's base seed.
pub fn case_seed(base: u64, format: &str, case: u64) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64 ^ base;
    for b in format.bytes() {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    Rng::new(h ^ case.wrapping_mul(0x9e37_79b9_7f4a_7c15)).next_u64()
}

/// Numbers that break code written for tame ones: non-finite, zero, negative, huge, tiny,
/// the edges of the integer types, and counts that are too large to allocate.
const NUMBERS: &[&str] = &[
    "NaN",
    "inf",
    "-inf",
    "0",
    "-0.0",
    "-1",
    "1e30",
    "-1e30",
    "1e-30",
    "3.4e38",
    "1e39",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "100000",
    "1000000000",
    "0.5",
    "7",
];

/// Strings that break code written for tame ones: empty, wildcards, paths that are not
/// regular files or lead elsewhere, very long ones.
const STRINGS: &[&str] = &[
    "",
    "*",
    "#0",
    "[*]",
    "/dev/zero",
    "/",
    "../../../../../../etc/passwd",
    "no_such_file.ron",
    "x[99999999999]",
    "\\u{0}",
];

/// Where the numeric literals of a text stand (byte ranges): optional sign, digits, a
/// fraction and an exponent. Digits inside identifiers (`obj012`) are not numbers.
fn number_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let c = text[i];
        let prev_ident = i > 0 && (text[i - 1].is_ascii_alphanumeric() || text[i - 1] == b'_');
        if (c.is_ascii_digit() || (c == b'-' && text.get(i + 1).is_some_and(u8::is_ascii_digit)))
            && !prev_ident
        {
            let start = i;
            i += 1;
            while i < text.len()
                && (text[i].is_ascii_digit()
                    || text[i] == b'.'
                    || text[i] == b'e'
                    || text[i] == b'E'
                    || ((text[i] == b'-' || text[i] == b'+') && matches!(text[i - 1], b'e' | b'E')))
            {
                i += 1;
            }
            if i < text.len() && (text[i].is_ascii_alphabetic() || text[i] == b'_') {
                // part of an identifier after all (`1st`)
                while i < text.len() && (text[i].is_ascii_alphanumeric() || text[i] == b'_') {
                    i += 1;
                }
                continue;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// Where the contents of the string literals of a text stand (inside the quotes).
fn string_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < text.len() {
        if text[i] == b'"' {
            let start = i + 1;
            i += 1;
            while i < text.len() && text[i] != b'"' {
                if text[i] == b'\\' {
                    i += 1;
                }
                i += 1;
            }
            spans.push((start, i.min(text.len())));
        }
        i += 1;
    }
    spans
}

fn line_starts(text: &[u8]) -> Vec<usize> {
    let mut v = vec![0];
    v.extend(text.iter().enumerate().filter(|(_, c)| **c == b'\n').map(|(k, _)| k + 1));
    v
}

fn splice(text: &mut Vec<u8>, (a, b): (usize, usize), with: &[u8]) {
    text.splice(a..b, with.iter().copied());
}

/// One mutation of a text: a number or a string replaced by a hostile one, a line deleted,
/// doubled or swapped, a span cut out or the text truncated. Returns what it did.
pub fn mutate_text_once(rng: &mut Rng, text: &mut Vec<u8>) -> String {
    if text.is_empty() {
        text.extend_from_slice(b"(");
        return "empty text: wrote \"(\"".into();
    }
    match rng.below(10) {
        0..=3 => {
            let spans = number_spans(text);
            if spans.is_empty() {
                return mutate_text_once(rng, text);
            }
            let span = *rng.pick(&spans);
            let with = *rng.pick(NUMBERS);
            let what = format!(
                "number {:?} at byte {} -> {with}",
                String::from_utf8_lossy(&text[span.0..span.1]),
                span.0
            );
            splice(text, span, with.as_bytes());
            what
        }
        4 => {
            let spans = string_spans(text);
            if spans.is_empty() {
                return mutate_text_once(rng, text);
            }
            let span = *rng.pick(&spans);
            // another string of the same text, or a hostile one
            let with: Vec<u8> = if rng.chance(0.5) {
                let other = *rng.pick(&spans);
                text[other.0..other.1].to_vec()
            } else {
                rng.pick(STRINGS).as_bytes().to_vec()
            };
            let what = format!(
                "string {:?} at byte {} -> {:?}",
                String::from_utf8_lossy(&text[span.0..span.1]),
                span.0,
                String::from_utf8_lossy(&with)
            );
            splice(text, span, &with);
            what
        }
        5 | 6 => {
            let starts = line_starts(text);
            let k = rng.below(starts.len());
            let a = starts[k];
            let b = starts.get(k + 1).copied().unwrap_or(text.len());
            let line = text[a..b].to_vec();
            if rng.chance(0.5) {
                // the same line many times over: a cheap way to many items
                let times = if rng.chance(0.2) { 200 } else { 1 };
                for _ in 0..times {
                    text.splice(b..b, line.iter().copied());
                }
                format!("line {} doubled {times} times", k + 1)
            } else {
                text.drain(a..b);
                format!("line {} deleted", k + 1)
            }
        }
        7 => {
            let starts = line_starts(text);
            let (i, j) = (rng.below(starts.len()), rng.below(starts.len()));
            let (i, j) = (i.min(j), i.max(j));
            if i == j {
                return mutate_text_once(rng, text);
            }
            let len = text.len();
            let end = |k: usize| starts.get(k + 1).copied().unwrap_or(len);
            let (ei, ej) = (end(i), end(j));
            let (a, b) = (text[starts[i]..ei].to_vec(), text[starts[j]..ej].to_vec());
            // replace the later one first so the earlier offsets stay valid
            text.splice(starts[j]..ej, a);
            text.splice(starts[i]..ei, b);
            format!("lines {} and {} swapped", i + 1, j + 1)
        }
        8 => {
            let a = rng.below(text.len());
            let n = 1 + rng.below(16.min(text.len() - a));
            text.drain(a..a + n);
            format!("{n} bytes cut at {a}")
        }
        _ => {
            let at = rng.below(text.len());
            text.truncate(at);
            format!("truncated to {at} bytes")
        }
    }
}

/// One to four mutations of a text. Returns what was done, for the failure report.
pub fn mutate_text(rng: &mut Rng, text: &mut Vec<u8>) -> Vec<String> {
    let n = 1 + rng.below(4);
    (0..n).map(|_| mutate_text_once(rng, text)).collect()
}

/// A safetensors file split into its parts: the JSON header and the data after it.
fn split_safetensors(bytes: &[u8]) -> Option<(usize, usize)> {
    let n = u64::from_le_bytes(bytes.get(..8)?.try_into().ok()?) as usize;
    (8usize.checked_add(n)? <= bytes.len()).then_some((8, 8 + n))
}

/// Mutations of a safetensors file: its JSON header (shapes, offsets, dtypes, the metadata
/// that holds a field's configuration) as text, its header length, or its data (NaN and
/// infinity written over values, bytes flipped), or the file truncated.
pub fn mutate_safetensors(rng: &mut Rng, bytes: &mut Vec<u8>) -> Vec<String> {
    let Some((h0, h1)) = split_safetensors(bytes) else {
        return mutate_text(rng, bytes);
    };
    match rng.below(10) {
        0..=4 => {
            let mut header = bytes[h0..h1].to_vec();
            let what = mutate_text(rng, &mut header);
            let data = bytes[h1..].to_vec();
            bytes.clear();
            bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
            bytes.extend_from_slice(&header);
            bytes.extend_from_slice(&data);
            what.into_iter().map(|w| format!("header: {w}")).collect()
        }
        5..=7 => {
            // non-finite, huge or merely unusual values over f32 data, one or a run of them
            // (the unusual ones load, so the renderer sees perturbed parameters too)
            let data_len = bytes.len() - h1;
            if data_len < 4 {
                return vec!["no data to poison".into()];
            }
            let bad =
                *rng.pick(&[f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 3.0e38, 1.0e3, -50.0]);
            let start = h1 + rng.below(data_len / 4) * 4;
            let run = if rng.chance(0.3) { data_len } else { 1 + rng.below(8) };
            let mut k = start;
            let mut n = 0;
            while k + 4 <= bytes.len() && n < run {
                bytes[k..k + 4].copy_from_slice(&bad.to_le_bytes());
                k += 4;
                n += 1;
            }
            vec![format!("{n} values at byte {start} set to {bad}")]
        }
        8 => {
            let v = *rng.pick(&[0u64, 1, (h1 - h0) as u64 + 1, u64::MAX, 1 << 40]);
            bytes[..8].copy_from_slice(&v.to_le_bytes());
            vec![format!("header length set to {v}")]
        }
        _ => {
            let at = rng.below(bytes.len());
            bytes.truncate(at);
            vec![format!("truncated to {at} bytes")]
        }
    }
}

/// Checks of the mutator itself, run before any case (this target has no test harness).
pub fn self_check() {
    let t = b"Row(count: 12, at: (-1.5e3, 0)), obj012";
    let found: Vec<&[u8]> = number_spans(t).iter().map(|&(a, b)| &t[a..b]).collect();
    assert_eq!(found, [&b"12"[..], b"-1.5e3", b"0"], "numbers outside identifiers");
    let (mut a, mut b) = (t.to_vec(), t.to_vec());
    mutate_text(&mut Rng::new(7), &mut a);
    mutate_text(&mut Rng::new(7), &mut b);
    assert_eq!(a, b, "the same seed must give the same mutation");
}
