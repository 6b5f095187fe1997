//! Observed surface points, grouped by frame, and their CSV files (interface.md,
//! "Observations (CSV)").
//!
//! # File format
//!
//! ```text
//! frame,x,y,z[,camera][,weight]
//! 0,0.12,1.31,-0.05,0
//! ```
//!
//! The first line is the header: it names the columns, `frame`, `x`, `y`, `z` required,
//! `camera` and `weight` optional, in any order, each at most once (names are matched
//! case-insensitively, surrounding spaces ignored). Every following non-blank line holds
//! one point with exactly one field per column: `frame` a non-negative integer (the state
//! after that many steps; frame 0 is the reference configuration), `x, y, z` finite world
//! coordinates, `camera` a non-negative integer or empty (no camera), `weight` a finite,
//! non-negative number, 0 or at least `f64::MIN_POSITIVE` (default 1 when the column is
//! absent; weights are relative, see [`crate::fit::uncertainty`]). Any number of points per
//! frame; frames may be missing and need not be sorted. A line that cannot be parsed is an
//! error naming the file, the line number and the problem, never skipped.
//!
//! [`Observations::write_csv`] writes `frame,x,y,z`, plus `camera` when some point has
//! one and `weight` when some weight differs from 1; numbers are written in Rust's
//! shortest round-trip form, so reading a written file gives back the same set.

use crate::Error;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// One observed surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObservedPoint {
    /// world position
    pub position: [f64; 3],
    /// the camera (or scan) that saw it, when known
    pub camera: Option<u32>,
    /// weight of the point in the cost (`w_{t,i}` of eq. 5.4.4), default 1
    pub weight: f64,
}

impl ObservedPoint {
    /// A point with no camera and weight 1.
    pub fn new(position: [f64; 3]) -> Self {
        ObservedPoint {
            position,
            camera: None,
            weight: 1.0,
        }
    }
}

/// A set of observed points grouped by frame (frames in increasing order; a frame without
/// points is absent).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Observations {
    frames: BTreeMap<usize, Vec<ObservedPoint>>,
}

/// The smallest largest weight a usable observation set may have: `sqrt(f64::MIN_POSITIVE)`
/// (about 1.5e-154). The optimizer squares gradients and Gauss-Newton entries, which carry one
/// weight each; below this their squares are subnormal or zero and the fit "converges" where
/// it started. Weights are relative (a fit and its standard errors do not change when all are
/// scaled), so such a set is refused with the advice to rescale it.
pub const MIN_USEFUL_WEIGHT: f64 = 1.4916681462400413e-154;

/// The header a file is expected to have (for messages).
const EXPECTED: &str = "frame,x,y,z[,camera][,weight]";

#[derive(Clone, Copy, Debug, PartialEq)]
enum Column {
    Frame,
    X,
    Y,
    Z,
    Camera,
    Weight,
}

impl Observations {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a point to `frame`.
    pub fn push(&mut self, frame: usize, point: ObservedPoint) {
        self.frames.entry(frame).or_default().push(point);
    }

    /// The points of `frame` (empty when it has none).
    pub fn frame(&self, frame: usize) -> &[ObservedPoint] {
        self.frames.get(&frame).map_or(&[], Vec::as_slice)
    }

    /// The frames with points and their points, in increasing frame order.
    pub fn frames(&self) -> impl Iterator<Item = (usize, &[ObservedPoint])> + '_ {
        self.frames.iter().map(|(&f, p)| (f, p.as_slice()))
    }

    /// A fingerprint of the data (`cutfem::input::digest` of every point's frame, position,
    /// camera and weight, in order; 16 hex digits): the same for the same points however the
    /// file spelled them, so runs on one recording can be told from runs on another.
    pub fn fingerprint(&self) -> String {
        let mut bytes = Vec::new();
        for (f, pts) in &self.frames {
            bytes.extend((*f as u64).to_le_bytes());
            for p in pts {
                for x in p.position {
                    bytes.extend(x.to_bits().to_le_bytes());
                }
                bytes.extend(p.camera.map_or(u64::MAX, u64::from).to_le_bytes());
                bytes.extend(p.weight.to_bits().to_le_bytes());
            }
        }
        format!("{:016x}", cutfem::input::digest(&bytes))
    }

    /// The numbers of the frames that have points, increasing.
    pub fn frame_numbers(&self) -> Vec<usize> {
        self.frames.keys().copied().collect()
    }

    /// Number of frames with points.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// The largest frame number, `None` when empty.
    pub fn last_frame(&self) -> Option<usize> {
        self.frames.keys().next_back().copied()
    }

    /// Total number of points.
    pub fn len(&self) -> usize {
        self.frames.values().map(Vec::len).sum()
    }

    /// Whether there is no point.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Sum of the weights of all points.
    pub fn total_weight(&self) -> f64 {
        self.frames.values().flatten().map(|p| p.weight).sum()
    }

    /// Errors, naming `path`, unless some point can inform a fit of `steps` steps: a point
    /// informs it when its weight is positive and its frame lies in `1..=steps` (frame 0 is the
    /// reference configuration, which no parameter changes; a frame beyond the steps is never
    /// simulated). The largest weight of those points must be at least [`MIN_USEFUL_WEIGHT`].
    /// The message counts the points of each kind that cannot.
    pub fn check_informative(&self, path: &Path, steps: usize) -> Result<(), Error> {
        let (mut total, mut zero, mut at0, mut beyond, mut usable) = (0usize, 0usize, 0usize, 0usize, 0usize);
        let mut w_max = 0.0f64;
        for (f, pts) in self.frames() {
            for p in pts {
                total += 1;
                if p.weight.is_nan() || p.weight <= 0.0 {
                    zero += 1;
                } else if f == 0 {
                    at0 += 1;
                } else if f > steps {
                    beyond += 1;
                } else {
                    usable += 1;
                    w_max = w_max.max(p.weight);
                }
            }
        }
        if total == 0 {
            return Err(Error::format(
                path,
                "no observed point (only a header): nothing to fit",
            ));
        }
        if usable == 0 {
            let mut why = Vec::new();
            if zero > 0 {
                why.push(format!("{zero} have weight 0"));
            }
            if at0 > 0 {
                why.push(format!(
                    "{at0} lie at frame 0 (the reference configuration, which no parameter changes)"
                ));
            }
            if beyond > 0 {
                why.push(format!("{beyond} lie beyond the {steps} simulated steps"));
            }
            return Err(Error::format(
                path,
                format!(
                    "none of the {total} observed points can inform the fit: {}; \
                 observations need a positive weight and a frame in 1..={steps}",
                    why.join(", ")
                ),
            ));
        }
        if w_max < MIN_USEFUL_WEIGHT {
            return Err(Error::format(
                path,
                format!(
                "the largest weight of the {usable} usable points is {w_max:e}, below {MIN_USEFUL_WEIGHT:e}: \
                 the squares of the cost's terms underflow; rescale the weights (only their ratios matter)"
            ),
            ));
        }
        Ok(())
    }

    /// Reads a CSV file (see the module docs for the format).
    pub fn read_csv(path: impl AsRef<Path>) -> Result<Self, Error> {
        let path = path.as_ref();
        let bytes = cutfem::input::read_text(path, cutfem::input::MAX_DATA_BYTES)
            .map_err(|source| Error::io(path, source))?;
        let text = String::from_utf8(bytes).map_err(|e| {
            let line = e.as_bytes()[..e.utf8_error().valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count()
                + 1;
            Error::Parse {
                path: path.to_path_buf(),
                line,
                msg: "not UTF-8 text".into(),
            }
        })?;
        Self::parse_csv(&text, path)
    }

    /// Parses CSV text; `path` names the file in errors.
    pub fn parse_csv(text: &str, path: &Path) -> Result<Self, Error> {
        let err = |line: usize, msg: String| Error::Parse {
            path: path.to_path_buf(),
            line,
            msg,
        };
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
        let Some((hline, header)) = lines.find(|(_, l)| !l.is_empty()) else {
            return Err(err(1, format!("empty file: expected the header {EXPECTED}")));
        };
        let columns = parse_header(header).map_err(|m| err(hline, m))?;
        let mut obs = Observations::new();
        for (n, line) in lines {
            if line.is_empty() {
                continue;
            }
            let (frame, point) = parse_line(line, &columns).map_err(|m| err(n, m))?;
            obs.push(frame, point);
        }
        Ok(obs)
    }

    /// The CSV text of the set (see the module docs).
    pub fn to_csv(&self) -> String {
        let points = self.frames.values().flatten();
        let cameras = points.clone().any(|p| p.camera.is_some());
        let weights = points.clone().any(|p| p.weight != 1.0);
        let mut s = String::from("frame,x,y,z");
        s += if cameras { ",camera" } else { "" };
        s += if weights { ",weight" } else { "" };
        s.push('\n');
        for (f, p) in self.frames() {
            for q in p {
                let [x, y, z] = q.position;
                let _ = write!(s, "{f},{x},{y},{z}");
                if cameras {
                    s.push(',');
                    if let Some(c) = q.camera {
                        let _ = write!(s, "{c}");
                    }
                }
                if weights {
                    let _ = write!(s, ",{}", q.weight);
                }
                s.push('\n');
            }
        }
        s
    }

    /// Writes the set as a CSV file.
    pub fn write_csv(&self, path: impl AsRef<Path>) -> Result<(), Error> {
        let path = path.as_ref();
        std::fs::write(path, self.to_csv()).map_err(|source| Error::io(path, source))
    }
}

/// The column a header name (any case) names.
fn column_named(name: &str) -> Option<Column> {
    Some(match name.to_ascii_lowercase().as_str() {
        "frame" => Column::Frame,
        "x" => Column::X,
        "y" => Column::Y,
        "z" => Column::Z,
        "camera" => Column::Camera,
        "weight" => Column::Weight,
        _ => return None,
    })
}

fn parse_header(header: &str) -> Result<Vec<Column>, String> {
    let mut cols = Vec::new();
    for name in header.split(',') {
        let name = name.trim();
        let Some(col) = column_named(name) else {
            // several known names joined by another separator
            let other = [';', '\t', ' ', '|'].into_iter().find(|&c| {
                let parts: Vec<&str> = name.split(c).map(str::trim).filter(|p| !p.is_empty()).collect();
                parts.len() > 1 && parts.iter().all(|p| column_named(p).is_some())
            });
            let hint = if name.parse::<f64>().is_ok() {
                " (the header line is missing?)".to_string()
            } else if let Some(c) = other {
                format!(" (columns are separated by commas; this file separates them by {c:?})")
            } else {
                String::new()
            };
            return Err(format!(
                "unknown column {name:?} in the header{hint}; expected {EXPECTED}"
            ));
        };
        if cols.contains(&col) {
            return Err(format!("column {name:?} appears twice in the header"));
        }
        cols.push(col);
    }
    for (col, name) in [
        (Column::Frame, "frame"),
        (Column::X, "x"),
        (Column::Y, "y"),
        (Column::Z, "z"),
    ] {
        if !cols.contains(&col) {
            return Err(format!(
                "the header lacks the column {name:?}; expected {EXPECTED}"
            ));
        }
    }
    Ok(cols)
}

fn parse_line(line: &str, columns: &[Column]) -> Result<(usize, ObservedPoint), String> {
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    if fields.len() != columns.len() {
        return Err(format!(
            "expected {} fields, found {} in {line:?}",
            columns.len(),
            fields.len()
        ));
    }
    let mut frame = 0;
    let mut point = ObservedPoint::new([0.0; 3]);
    for (&col, &field) in columns.iter().zip(&fields) {
        // a bad field is repeated up to 100 characters
        let shown = cutfem::scene::quote(field, cutfem::scene::MAX_QUOTE);
        match col {
            Column::Frame => {
                frame = match field.parse::<i64>() {
                    Ok(f) if f < 0 => return Err(format!("negative frame {f}")),
                    Ok(f) => usize::try_from(f).map_err(|_| format!("frame {f} is too large"))?,
                    Err(_) => return Err(format!("frame must be a non-negative integer, found {shown:?}")),
                }
            }
            Column::X | Column::Y | Column::Z => {
                let a = match col {
                    Column::X => 0,
                    Column::Y => 1,
                    _ => 2,
                };
                let name = ["x", "y", "z"][a];
                let v: f64 = field
                    .parse()
                    .map_err(|_| format!("{name} is not a number: {shown:?}"))?;
                if !v.is_finite() {
                    return Err(format!("{name} is not finite: {shown:?}"));
                }
                point.position[a] = v;
            }
            Column::Camera => {
                point.camera = if field.is_empty() {
                    None
                } else {
                    Some(field.parse::<u32>().map_err(|_| {
                        format!("camera must be a non-negative integer or empty, found {shown:?}")
                    })?)
                };
            }
            Column::Weight => {
                let w: f64 = field
                    .parse()
                    .map_err(|_| format!("weight is not a number: {shown:?}"))?;
                if !w.is_finite() {
                    return Err(format!("weight is not finite: {shown:?}"));
                }
                if w < 0.0 {
                    return Err(format!("negative weight {w}"));
                }
                if w > 0.0 && w < f64::MIN_POSITIVE {
                    // a subnormal weight: its products with squared residuals underflow to 0
                    return Err(format!(
                        "weight {w:e} is subnormal (below {:e}): it cannot weigh a point; \
                         use 0 to drop the point or rescale all weights",
                        f64::MIN_POSITIVE
                    ));
                }
                point.weight = w;
            }
        }
    }
    Ok((frame, point))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Observations, String> {
        Observations::parse_csv(text, Path::new("obs.csv")).map_err(|e| e.to_string())
    }

    #[test]
    fn data_that_cannot_inform_a_fit_are_named() {
        let check = |text: &str| parse(text).unwrap().check_informative(Path::new("o.csv"), 4);
        check("frame,x,y,z\n1,0,0,0\n").unwrap();
        check("frame,x,y,z,weight\n4,0,0,0,1e-150\n0,0,0,0,1\n").unwrap();
        let e = check("frame,x,y,z,weight\n1,0,0,0,0\n0,0,0,0,2\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "o.csv: none of the 2 observed points can inform the fit: 1 have weight 0, 1 lie at frame 0"
            ),
            "{e}"
        );
        let e = check("frame,x,y,z,weight\n2,0,0,0,1e-160\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("largest weight of the 1 usable points is 1e-160"),
            "{e}"
        );
        let e = check("frame,x,y,z\n9,0,0,0\n").unwrap_err().to_string();
        assert!(e.contains("1 lie beyond the 4 simulated steps"), "{e}");
        assert!(check("frame,x,y,z\n")
            .unwrap_err()
            .to_string()
            .contains("no observed point"));
        let e = parse("frame,x,y,z,weight\n1,0,0,0,5e-324\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2: weight 5e-324 is subnormal"), "{e}");
    }

    #[test]
    fn reads_all_column_layouts() {
        let o = parse("frame,x,y,z\n0,1,2,3\n2,0.5,-1e-3,4\n\n0,7,8,9\n").unwrap();
        assert_eq!(o.len(), 3);
        assert_eq!(o.frame_numbers(), vec![0, 2]);
        assert_eq!(o.frame(0)[1], ObservedPoint::new([7.0, 8.0, 9.0]));
        assert_eq!(o.frame(1), &[]);
        assert_eq!(o.last_frame(), Some(2));
        let o = parse("frame,x,y,z,camera\r\n1,1,2,3,4\r\n1,1,2,3,\r\n").unwrap();
        assert_eq!(o.frame(1)[0].camera, Some(4));
        assert_eq!(o.frame(1)[1].camera, None);
        let o = parse("\u{feff}Frame, X, Y, Z, weight, camera\n3, 1, 2, 3, 0.25, 1\n").unwrap();
        let p = o.frame(3)[0];
        assert_eq!((p.weight, p.camera, p.position), (0.25, Some(1), [1.0, 2.0, 3.0]));
        assert_eq!(o.total_weight(), 0.25);
        let o = parse("frame,x,y,z\n").unwrap();
        assert!(o.is_empty() && o.frame_count() == 0);
    }

    #[test]
    fn bad_input_names_file_line_and_problem() {
        let cases = [
            ("", "obs.csv: line 1: empty file"),
            (
                "0,1,2,3\n",
                "line 1: unknown column \"0\" in the header (the header line is missing?)",
            ),
            ("frame,x,y\n0,1,2\n", "line 1: the header lacks the column \"z\""),
            ("frame,x,y,z,x\n", "line 1: column \"x\" appears twice"),
            ("frame,x,y,z,colour\n", "unknown column \"colour\""),
            (
                "frame;x;y;z\n1;0;0;0\n",
                "unknown column \"frame;x;y;z\" in the header (columns are separated by commas; this file separates them by ';')",
            ),
            (
                "Frame\tX\tY\tZ\n",
                "this file separates them by '\\t'",
            ),
            (
                "frame,x,y,z\n0,1,2,3\n0,1,2\n",
                "line 3: expected 4 fields, found 3",
            ),
            ("frame,x,y,z\n0,1,2,3,\n", "line 2: expected 4 fields, found 5"),
            ("frame,x,y,z\n-1,1,2,3\n", "line 2: negative frame -1"),
            (
                "frame,x,y,z\n1.5,1,2,3\n",
                "line 2: frame must be a non-negative integer",
            ),
            ("frame,x,y,z\n1,1,NaN,3\n", "line 2: y is not finite"),
            ("frame,x,y,z\n1,1,2,inf\n", "line 2: z is not finite"),
            ("frame,x,y,z\n1,a,2,3\n", "line 2: x is not a number: \"a\""),
            ("frame,x,y,z\n1,,2,3\n", "line 2: x is not a number"),
            (
                "frame,x,y,z,weight\n\n1,1,2,3,-0.5\n",
                "line 3: negative weight -0.5",
            ),
            (
                "frame,x,y,z,weight\n1,1,2,3,nan\n",
                "line 2: weight is not finite",
            ),
            (
                "frame,x,y,z,camera\n1,1,2,3,-1\n",
                "line 2: camera must be a non-negative integer",
            ),
        ];
        for (text, needle) in cases {
            let e = parse(text).expect_err(text);
            assert!(e.contains(needle), "`{needle}` not in `{e}`");
            assert!(e.starts_with("obs.csv: line "), "{e}");
            assert_eq!(e.lines().count(), 1);
        }
    }

    #[test]
    fn write_then_read_round_trips() {
        let dir = std::env::temp_dir().join(format!("adjoint-obs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut o = Observations::new();
        o.push(3, ObservedPoint::new([0.1, 1.0 / 3.0, -2e-17]));
        o.push(
            1,
            ObservedPoint {
                position: [1.0, 2.0, 3.0],
                camera: Some(2),
                weight: 0.5,
            },
        );
        let path = dir.join("o.csv");
        o.write_csv(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.starts_with("frame,x,y,z,camera,weight\n1,1,2,3,2,0.5\n"),
            "{text}"
        );
        assert_eq!(Observations::read_csv(&path).unwrap(), o);
        // plain points: only the required columns
        let mut plain = Observations::new();
        plain.push(0, ObservedPoint::new([1.5, 2.0, 3.0]));
        assert_eq!(plain.to_csv(), "frame,x,y,z\n0,1.5,2,3\n");
        // missing file: one line with the path
        let e = Observations::read_csv(dir.join("missing.csv"))
            .unwrap_err()
            .to_string()
            .to_string();
        assert!(e.contains("missing.csv") && e.lines().count() == 1, "{e}");
        std::fs::write(&path, b"frame,x,y,z\n0,1,2,\xff\n").unwrap();
        let e = Observations::read_csv(&path).unwrap_err().to_string();
        assert!(e.contains("line 2: not UTF-8"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
