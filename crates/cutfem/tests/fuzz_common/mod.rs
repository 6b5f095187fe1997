//! Shared by the parser fuzz tests (`cutfem/tests/scene_fuzz.rs`, `adjoint/tests/parsers_fuzz.rs`,
//! which includes this file by path): the proptest configuration and the strategies of hostile
//! text, random bytes and random mutations of a valid file.
//!
//! Cases: [`DEFAULT_CASES`] per property (a few seconds in CI); `PROPTEST_CASES=N` runs `N`.

#![allow(dead_code)] // each test file uses its own subset

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::Config;

/// Cases per property when `PROPTEST_CASES` is not set.
pub const DEFAULT_CASES: u32 = 512;

/// `PROPTEST_CASES` (default [`DEFAULT_CASES`]), no failure files in the source tree.
pub fn config() -> Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(DEFAULT_CASES);
    Config {
        failure_persistence: None,
        ..Config::with_cases(cases)
    }
}

/// Values that break naive number handling: huge, tiny, negative, non-finite, overflowing
/// integers, odd syntax.
pub const HOSTILE_NUMBERS: &[&str] = &[
    "0",
    "-0.0",
    "-1",
    "-5",
    "1e308",
    "-1e308",
    "1e309",
    "1.7976931348623157e308",
    "4.9e-324",
    "1e-320",
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999999999",
    "0x10",
    "1_000",
    "1e",
    "",
    "\"\"",
    "[]",
    "{}",
    "1.0.0",
];

/// A change to a text file.
#[derive(Clone, Debug)]
pub enum Mutation {
    /// xor a byte with a non-zero mask
    FlipByte(Index, u8),
    /// keep the first part
    Truncate(Index),
    /// repeat a line
    DuplicateLine(Index),
    /// drop a line
    RemoveLine(Index),
    /// exchange two lines
    SwapLines(Index, Index),
    /// replace a number (a run of digits, signs, dots, `e`) by a hostile one
    ReplaceNumber(Index, &'static str),
    /// insert syntax characters
    Insert(Index, String),
}

/// One mutation.
pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<Index>(), 1u8..=255).prop_map(|(i, m)| Mutation::FlipByte(i, m)),
        any::<Index>().prop_map(Mutation::Truncate),
        any::<Index>().prop_map(Mutation::DuplicateLine),
        any::<Index>().prop_map(Mutation::RemoveLine),
        (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        (any::<Index>(), proptest::sample::select(HOSTILE_NUMBERS))
            .prop_map(|(i, n)| Mutation::ReplaceNumber(i, n)),
        (any::<Index>(), "[\\[\\]{}=\",.#'\\n\\r\\\\ a-z0-9é\u{0}-]{1,6}")
            .prop_map(|(i, s)| Mutation::Insert(i, s)),
    ]
}

/// One to four mutations.
pub fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    proptest::collection::vec(mutation(), 1..=4)
}

/// Random bytes (up to 2 KiB), the most often printable ASCII.
pub fn bytes() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(
        prop_oneof![3 => 0x20u8..0x7f, 1 => Just(b'\n'), 1 => any::<u8>()],
        0..2048,
    )
}

/// `text` after the mutations (bytes: a flip may leave invalid UTF-8).
pub fn apply(text: &str, mutations: &[Mutation]) -> Vec<u8> {
    let mut b = text.as_bytes().to_vec();
    for m in mutations {
        b = apply_one(b, m);
    }
    b
}

fn lines(b: &[u8]) -> Vec<Vec<u8>> {
    b.split_inclusive(|&c| c == b'\n').map(<[u8]>::to_vec).collect()
}

fn apply_one(mut b: Vec<u8>, m: &Mutation) -> Vec<u8> {
    match m {
        Mutation::FlipByte(i, mask) if !b.is_empty() => {
            let i = i.index(b.len());
            b[i] ^= mask;
            b
        }
        Mutation::Truncate(i) => {
            b.truncate(i.index(b.len() + 1));
            b
        }
        Mutation::DuplicateLine(i) | Mutation::RemoveLine(i) => {
            let mut l = lines(&b);
            if l.is_empty() {
                return b;
            }
            let k = i.index(l.len());
            if matches!(m, Mutation::RemoveLine(_)) {
                l.remove(k);
            } else {
                let copy = l[k].clone();
                l.insert(k, copy);
            }
            l.concat()
        }
        Mutation::SwapLines(i, j) => {
            let mut l = lines(&b);
            if l.is_empty() {
                return b;
            }
            let (i, j) = (i.index(l.len()), j.index(l.len()));
            l.swap(i, j);
            l.concat()
        }
        Mutation::ReplaceNumber(i, n) => {
            let numbers = number_spans(&b);
            if numbers.is_empty() {
                return b;
            }
            let (s, e) = numbers[i.index(numbers.len())];
            b.splice(s..e, n.bytes());
            b
        }
        Mutation::Insert(i, s) => {
            let at = i.index(b.len() + 1);
            b.splice(at..at, s.bytes());
            b
        }
        Mutation::FlipByte(..) => b,
    }
}

/// Byte ranges of the numbers in `b`: runs of digits with their sign, dots and exponent.
fn number_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || (matches!(b[i], b'-' | b'+' | b'.') && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        // a digit inside a word (`x1`) is not a number
        let in_word = i > 0 && (b[i - 1].is_ascii_alphabetic() || b[i - 1] == b'_');
        if starts && !in_word {
            let s = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'e' | b'E' | b'-' | b'+')) {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}
