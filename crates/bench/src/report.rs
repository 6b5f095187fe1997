//! Markdown rendering of the JSON rows (a missing value, `null`, reads "not available").

use serde_json::Value;

/// How a column is printed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fmt {
    /// an integer or string as is
    Plain,
    /// seconds, printed in milliseconds
    SecondsAsMs,
    /// already milliseconds (thesis figures)
    Ms,
    /// GB/s, one decimal
    Gbs,
    /// a ratio, two decimals
    Ratio,
    /// a fraction, as a percentage
    Percent,
    /// scientific notation
    Sci,
}

/// A column: header, JSON key, format.
#[derive(Clone, Copy, Debug)]
pub struct Col {
    /// header text
    pub header: &'static str,
    /// key in the row object
    pub key: &'static str,
    /// format
    pub fmt: Fmt,
}

/// Shorthand for a [`Col`].
pub const fn col(header: &'static str, key: &'static str, fmt: Fmt) -> Col {
    Col { header, key, fmt }
}

/// Significant-digit formatting for times.
fn sig(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    let digits = 4i32;
    let mag = x.abs().log10().floor() as i32;
    let decimals = (digits - 1 - mag).clamp(0, 9) as usize;
    format!("{x:.decimals$}")
}

fn cell(v: Option<&Value>, fmt: Fmt) -> String {
    let Some(v) = v.filter(|v| !v.is_null()) else {
        return "not available".into();
    };
    if let Some(s) = v.as_str() {
        return s.to_string();
    }
    if let Some(b) = v.as_bool() {
        return if b { "yes".into() } else { "NO".into() };
    }
    let Some(x) = v.as_f64() else {
        return v.to_string();
    };
    match fmt {
        Fmt::Plain => v.to_string(),
        Fmt::SecondsAsMs => sig(x * 1e3),
        Fmt::Ms => sig(x),
        Fmt::Gbs => format!("{x:.1}"),
        Fmt::Ratio => format!("{x:.2}"),
        Fmt::Percent => format!("{:.0}%", x * 100.0),
        Fmt::Sci => format!("{x:.2e}"),
    }
}

/// A markdown table of `rows` (JSON objects) with the given columns, under a `###` title.
pub fn markdown_table(title: &str, note: &str, rows: &[Value], cols: &[Col]) -> String {
    let mut s = format!("### {title}\n\n");
    if !note.is_empty() {
        s.push_str(note);
        s.push_str("\n\n");
    }
    s.push('|');
    for c in cols {
        s.push_str(&format!(" {} |", c.header));
    }
    s.push_str("\n|");
    for _ in cols {
        s.push_str("---:|");
    }
    s.push('\n');
    for r in rows {
        s.push('|');
        for c in cols {
            s.push_str(&format!(" {} |", cell(r.get(c.key), c.fmt)));
        }
        s.push('\n');
    }
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nulls_read_not_available() {
        let rows = vec![serde_json::json!({"n": 10, "t": null, "u": 0.0012})];
        let md = markdown_table(
            "T",
            "",
            &rows,
            &[
                col("n", "n", Fmt::Plain),
                col("t", "t", Fmt::SecondsAsMs),
                col("u", "u", Fmt::SecondsAsMs),
            ],
        );
        assert!(md.contains("| 10 | not available | 1.200 |"), "{md}");
    }
}
