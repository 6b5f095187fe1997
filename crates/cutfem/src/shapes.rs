//! Analytic solids with exact signed distances, volumes and areas.
//!
//! Signed distances (negative inside), with `d = p - center`:
//!
//! * box of half-size `e = size / 2`: `q = |d| - e` (componentwise),
//!   `phi = |max(q, 0)| + min(max(q_x, q_y, q_z), 0)`;
//! * sphere: `phi = |d| - radius`;
//! * torus with unit axis `n`, major radius `R` (centre to tube centre), minor radius `r`
//!   (tube), `R > r`: with height `z = d.n` and radial distance `rho = |d - z n|`,
//!   `phi = sqrt((rho - R)^2 + z^2) - r`; volume `2 pi^2 R r^2`, area `4 pi^2 R r`;
//! * capsule (segment `[a, b]` of length `L` swept by a ball of radius `r`):
//!   `phi = |p - closest point of [a, b]| - r`; volume `pi r^2 L + 4/3 pi r^3`, area
//!   `2 pi r L + 4 pi r^2`.
//!
//! In a scene file a shape is written as a TOML inline table tagged by `kind`:
//! `shape = { kind = "box", center = [0, 1, 0], size = [1.29, 0.4, 0.8] }`.

use crate::v3::{dot, norm, sub};
use crate::{Error, SdfGrid};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// An analytic solid (see the module docs for the distance formulas).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Shape {
    /// Axis-aligned box.
    Box {
        /// centre
        center: [f64; 3],
        /// edge lengths along x, y, z
        size: [f64; 3],
    },
    /// Ball.
    Sphere {
        /// centre
        center: [f64; 3],
        /// radius
        radius: f64,
    },
    /// Ring torus around `axis` through `center`.
    Torus {
        /// centre
        center: [f64; 3],
        /// axis of revolution (any non-zero length; normalized internally)
        axis: [f64; 3],
        /// distance from the centre to the tube's centre line (R)
        major: f64,
        /// tube radius (r < R)
        minor: f64,
    },
    /// Segment `[a, b]` swept by a ball.
    Capsule {
        /// first end of the core segment
        a: [f64; 3],
        /// second end of the core segment
        b: [f64; 3],
        /// radius
        radius: f64,
    },
}

impl Shape {
    /// Checks the parameters: finite, positive sizes/radii, non-zero torus axis and
    /// `major > minor` (a ring torus; the formulas assume it).
    pub fn validate(&self) -> Result<(), Error> {
        let finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
        let bad = |msg: String| Err(Error::Invalid(format!("body.shape: {msg}")));
        match *self {
            Shape::Box { center, size } => {
                if !finite(&center) || !finite(&size) || size.iter().any(|&s| s <= 0.0) {
                    return bad(format!(
                        "box needs a finite center and positive size, found {center:?}, {size:?}"
                    ));
                }
            }
            Shape::Sphere { center, radius } => {
                if !(finite(&center) && radius.is_finite() && radius > 0.0) {
                    return bad(format!(
                        "sphere needs a finite center and positive radius, found {center:?}, {radius}"
                    ));
                }
            }
            Shape::Torus {
                center,
                axis,
                major,
                minor,
            } => {
                if !(finite(&center) && finite(&axis) && norm(axis) > 0.0) {
                    return bad(format!(
                        "torus needs a finite center and non-zero axis, found {center:?}, {axis:?}"
                    ));
                }
                if !(minor.is_finite() && major.is_finite() && minor > 0.0 && major > minor) {
                    return bad(format!(
                        "torus needs major > minor > 0, found major {major}, minor {minor}"
                    ));
                }
            }
            Shape::Capsule { a, b, radius } => {
                if !(finite(&a) && finite(&b) && radius.is_finite() && radius > 0.0) {
                    return bad(format!(
                        "capsule needs finite ends and a positive radius, found {a:?}, {b:?}, {radius}"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Exact signed distance from `p` to the surface (negative inside).
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        match *self {
            Shape::Box { center, size } => {
                let d = sub(p, center);
                let q: [f64; 3] = std::array::from_fn(|a| d[a].abs() - 0.5 * size[a]);
                let outside = norm(q.map(|x| x.max(0.0)));
                let inside = q[0].max(q[1]).max(q[2]).min(0.0);
                outside + inside
            }
            Shape::Sphere { center, radius } => norm(sub(p, center)) - radius,
            Shape::Torus {
                center,
                axis,
                major,
                minor,
            } => {
                let n = axis.map(|x| x / norm(axis));
                let d = sub(p, center);
                let z = dot(d, n);
                let rho = (dot(d, d) - z * z).max(0.0).sqrt();
                ((rho - major).powi(2) + z * z).sqrt() - minor
            }
            Shape::Capsule { a, b, radius } => {
                let ab = sub(b, a);
                let len2 = dot(ab, ab);
                let ap = sub(p, a);
                let t = if len2 > 0.0 {
                    (dot(ap, ab) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                norm(sub(ap, ab.map(|x| x * t))) - radius
            }
        }
    }

    /// Exact volume.
    pub fn volume(&self) -> f64 {
        match *self {
            Shape::Box { size, .. } => size[0] * size[1] * size[2],
            Shape::Sphere { radius, .. } => 4.0 / 3.0 * PI * radius.powi(3),
            Shape::Torus { major, minor, .. } => 2.0 * PI * PI * major * minor * minor,
            Shape::Capsule { a, b, radius } => {
                PI * radius * radius * norm(sub(b, a)) + 4.0 / 3.0 * PI * radius.powi(3)
            }
        }
    }

    /// Exact surface area.
    pub fn area(&self) -> f64 {
        match *self {
            Shape::Box { size: [x, y, z], .. } => 2.0 * (x * y + y * z + z * x),
            Shape::Sphere { radius, .. } => 4.0 * PI * radius * radius,
            Shape::Torus { major, minor, .. } => 4.0 * PI * PI * major * minor,
            Shape::Capsule { a, b, radius } => {
                2.0 * PI * radius * norm(sub(b, a)) + 4.0 * PI * radius * radius
            }
        }
    }

    /// Tight axis-aligned bounding box `(min, max)`.
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        let around = |c: [f64; 3], e: [f64; 3]| {
            (
                std::array::from_fn(|a| c[a] - e[a]),
                std::array::from_fn(|a| c[a] + e[a]),
            )
        };
        match *self {
            Shape::Box { center, size } => around(center, size.map(|s| 0.5 * s)),
            Shape::Sphere { center, radius } => around(center, [radius; 3]),
            Shape::Torus {
                center,
                axis,
                major,
                minor,
            } => {
                // the centre circle spans R sqrt(1 - n_a^2) along world axis a
                let n = axis.map(|x| x / norm(axis));
                around(
                    center,
                    n.map(|na| major * (1.0 - na * na).max(0.0).sqrt() + minor),
                )
            }
            Shape::Capsule { a, b, radius } => (
                std::array::from_fn(|k| a[k].min(b[k]) - radius),
                std::array::from_fn(|k| a[k].max(b[k]) + radius),
            ),
        }
    }

    /// Samples [`Shape::distance`] on a grid of spacing `1 / resolution` covering the bounding
    /// box plus `padding_cells` cells, nodes on multiples of the spacing
    /// (`origin = floor(min / h - padding) h`, see [`SdfGrid::covering_grid`]), and keeps the
    /// distance itself as the grid's [`SdfGrid::exact`] (sharp edges in the refined cut cells).
    ///
    /// Errors for invalid parameters, a non-positive resolution, or too many nodes (checked
    /// before allocating).
    pub fn to_sdf(&self, resolution: f64, padding_cells: usize) -> Result<SdfGrid, Error> {
        self.validate()?;
        let (lo, hi) = self.bounding_box();
        let (origin, dims) = SdfGrid::covering_grid(lo, hi, resolution, padding_cells)?;
        let mut grid = SdfGrid::from_fn(origin, 1.0 / resolution, dims, |p| self.distance(p));
        let shape = self.clone();
        grid.exact = Some(crate::sdf::ExactSdf(std::sync::Arc::new(move |p| {
            shape.distance(p)
        })));
        Ok(grid)
    }
}
