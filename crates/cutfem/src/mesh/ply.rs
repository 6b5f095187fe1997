//! PLY reader, `ascii 1.0`, `binary_little_endian 1.0` and `binary_big_endian 1.0`.
//!
//! The header declares elements (`element NAME COUNT`) with scalar properties
//! (`property TYPE NAME`) or list properties (`property list COUNT_TYPE ITEM_TYPE NAME`), types
//! `char uchar short ushort int uint float double` (or `int8 uint8 ... float64`). The `vertex`
//! element's `x`, `y`, `z` and the `face` element's `vertex_indices` (or `vertex_index`) list
//! are used, polygons fan-triangulated; other properties and elements are read and skipped.

use super::TriMesh;
use crate::Error;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }
    /// The value of `self.size()` bytes `raw` stored in the given byte order.
    fn read(self, raw: &[u8], big_endian: bool) -> f64 {
        let mut b = [0u8; 8];
        let b = &mut b[..raw.len()];
        b.copy_from_slice(raw);
        if big_endian {
            b.reverse();
        }
        match self {
            Ty::I8 => b[0] as i8 as f64,
            Ty::U8 => b[0] as f64,
            Ty::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F64 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }
}

#[derive(Debug)]
enum Prop {
    Scalar(Ty, String),
    List(Ty, Ty, String),
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

/// Source of values: ASCII tokens (one element instance per line) or bytes in either order.
enum Body<'a> {
    Ascii {
        lines: std::iter::Enumerate<std::str::Lines<'a>>,
        first_line: usize,
    },
    Binary {
        bytes: &'a [u8],
        at: usize,
        big_endian: bool,
    },
}

/// The body's encoding, from the header's `format` line.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    Binary { big_endian: bool },
}

/// Parses a PLY file's bytes; errors name the file and the header/body line (ASCII) or the
/// element and byte offset (binary).
pub(crate) fn parse(path: &Path, bytes: &[u8]) -> Result<TriMesh, Error> {
    let bad = |msg: String| Error::format(path, msg);
    // header: lines up to "end_header"
    let mut elements: Vec<Element> = Vec::new();
    let mut format = None;
    let mut at = 0usize;
    let mut lineno = 0usize;
    loop {
        let end = bytes[at..]
            .iter()
            .position(|&c| c == b'\n')
            .map(|e| at + e)
            .ok_or_else(|| bad(format!("line {}: header has no 'end_header'", lineno + 1)))?;
        lineno += 1;
        let line = String::from_utf8_lossy(&bytes[at..end]);
        at = end + 1;
        let err = |msg: String| Error::format(path, format!("line {lineno}: {msg}"));
        let tok: Vec<&str> = line.split_whitespace().collect();
        if lineno == 1 {
            if tok.first() != Some(&"ply") {
                return Err(err("not a PLY file (the first line must be 'ply')".into()));
            }
            continue;
        }
        match tok.first().copied() {
            Some("format") => {
                format = Some(match tok.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Binary { big_endian: false },
                    Some("binary_big_endian") => Format::Binary { big_endian: true },
                    Some(f) => {
                        return Err(err(format!(
                            "format '{f}' is not supported (ascii, binary_little_endian or binary_big_endian)"
                        )))
                    }
                    None => return Err(err("format line without a format".into())),
                });
            }
            Some("element") => {
                let (name, count) = match tok[..] {
                    [_, name, count] => (name, count),
                    _ => return Err(err("expected 'element NAME COUNT'".into())),
                };
                let count = count
                    .parse()
                    .map_err(|_| err(format!("bad element count '{count}'")))?;
                elements.push(Element {
                    name: name.into(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| err("property before any element".into()))?;
                let ty = |s: &str| Ty::parse(s).ok_or_else(|| err(format!("unknown property type '{s}'")));
                let prop = match tok[..] {
                    [_, "list", ct, it, name] => {
                        let (ct, it) = (ty(ct)?, ty(it)?);
                        if matches!(ct, Ty::F32 | Ty::F64) {
                            return Err(err("list count type must be an integer type".into()));
                        }
                        Prop::List(ct, it, name.into())
                    }
                    [_, t, name] => Prop::Scalar(ty(t)?, name.into()),
                    _ => {
                        return Err(err(
                            "expected 'property TYPE NAME' or 'property list CT IT NAME'".into()
                        ))
                    }
                };
                el.props.push(prop);
            }
            Some("end_header") => break,
            Some("comment" | "obj_info") | None => {}
            Some(other) => return Err(err(format!("unexpected header keyword '{other}'"))),
        }
    }
    let format = format.ok_or_else(|| bad("header has no 'format' line".into()))?;
    let mut body = if let Format::Binary { big_endian } = format {
        Body::Binary {
            bytes,
            at,
            big_endian,
        }
    } else {
        let text = std::str::from_utf8(&bytes[at..]).map_err(|_| bad("ASCII body is not text".into()))?;
        Body::Ascii {
            lines: text.lines().enumerate(),
            first_line: lineno + 1,
        }
    };
    let mut mesh = TriMesh::default();
    let mut faces: Vec<(Vec<f64>, String)> = Vec::new();
    for el in &elements {
        let find = |n: &str| {
            el.props
                .iter()
                .position(|p| matches!(p, Prop::Scalar(_, name) if name == n))
        };
        let xyz = [find("x"), find("y"), find("z")];
        let list = el.props.iter().position(
            |p| matches!(p, Prop::List(_, _, name) if name == "vertex_indices" || name == "vertex_index"),
        );
        if el.name == "vertex" && xyz.iter().any(Option::is_none) {
            return Err(bad("the vertex element lacks an x, y or z property".into()));
        }
        if el.name == "face" && list.is_none() {
            return Err(bad("the face element lacks a vertex_indices list".into()));
        }
        for inst in 0..el.count {
            let (values, place) = read_instance(path, &mut body, el, inst)?;
            if el.name == "vertex" {
                let p = xyz.map(|i| values[i.unwrap_or(0)][0]);
                if p.iter().any(|x| !x.is_finite()) {
                    return Err(bad(format!("{place}: non-finite vertex coordinate")));
                }
                mesh.vertices.push(p);
            } else if el.name == "face" {
                faces.push((values[list.unwrap_or(0)].clone(), place));
            }
        }
    }
    let nv = mesh.vertices.len();
    for (idx, place) in faces {
        if idx.len() < 3 {
            return Err(bad(format!(
                "{place}: face needs at least 3 vertices, found {}",
                idx.len()
            )));
        }
        if let Some(b) = idx
            .iter()
            .find(|&&i| !(i >= 0.0 && i < nv as f64 && i.fract() == 0.0))
        {
            return Err(bad(format!(
                "{place}: vertex index {b} out of range (the file has {nv} vertices)"
            )));
        }
        for k in 1..idx.len() - 1 {
            mesh.faces.push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
    }
    Ok(mesh)
}

/// Reads one element instance: each property's values (1 for scalars) and a place description.
fn read_instance(
    path: &Path,
    body: &mut Body<'_>,
    el: &Element,
    inst: usize,
) -> Result<(Vec<Vec<f64>>, String), Error> {
    let mut out = Vec::with_capacity(el.props.len());
    match body {
        Body::Ascii { lines, first_line } => {
            let (n, line) = loop {
                match lines.next() {
                    Some((_, l)) if l.trim().is_empty() => continue,
                    Some((n, l)) => break (n, l),
                    None => {
                        return Err(Error::format(
                            path,
                            format!(
                                "unexpected end of file: {} {inst} of {} missing",
                                el.name, el.count
                            ),
                        ))
                    }
                }
            };
            let place = format!("line {}", *first_line + n);
            let err = |msg: String| Error::format(path, format!("{place}: {msg}"));
            let mut tok = line.split_whitespace();
            let mut num = |what: &str| -> Result<f64, Error> {
                let t = tok
                    .next()
                    .ok_or_else(|| err(format!("{} {inst}: missing {what}", el.name)))?;
                t.parse::<f64>()
                    .map_err(|_| err(format!("{} {inst}: bad number '{t}'", el.name)))
            };
            for p in &el.props {
                match p {
                    Prop::Scalar(_, name) => out.push(vec![num(name)?]),
                    Prop::List(_, _, name) => {
                        let c = num(name)?;
                        if !(c >= 0.0 && c.fract() == 0.0 && c < 1e6) {
                            return Err(err(format!("{} {inst}: bad list length {c}", el.name)));
                        }
                        let items = (0..c as usize).map(|_| num(name)).collect::<Result<_, _>>()?;
                        out.push(items);
                    }
                }
            }
            Ok((out, place))
        }
        Body::Binary {
            bytes,
            at,
            big_endian,
        } => {
            let place = format!("{} {inst} (byte {at})", el.name);
            let mut take = |t: Ty| -> Result<f64, Error> {
                let end = *at + t.size();
                if end > bytes.len() {
                    return Err(Error::format(
                        path,
                        format!(
                            "truncated binary body: {} {inst} of {} needs byte {end}, file has {}",
                            el.name,
                            el.count,
                            bytes.len()
                        ),
                    ));
                }
                let v = t.read(&bytes[*at..end], *big_endian);
                *at = end;
                Ok(v)
            };
            for p in &el.props {
                match p {
                    Prop::Scalar(t, _) => out.push(vec![take(*t)?]),
                    Prop::List(ct, it, _) => {
                        let c = take(*ct)?;
                        if c < 0.0 {
                            return Err(Error::format(path, format!("{place}: negative list length {c}")));
                        }
                        let items = (0..c as usize).map(|_| take(*it)).collect::<Result<_, _>>()?;
                        out.push(items);
                    }
                }
            }
            Ok((out, place))
        }
    }
}
