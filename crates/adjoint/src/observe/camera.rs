//! The pinhole camera of the virtual RGB-D sensor: projection and unprojection.
//!
//! # Frame
//!
//! From the eye `e`, the target `t` and the world up direction `a` (normally +y):
//! `forward = (t - e) / |t - e|`, `right = forward x a / |forward x a|`,
//! `up = right x forward` (an orthonormal, right-handed frame; when `a` is parallel to the
//! view direction another axis is used instead).
//!
//! # Projection
//!
//! A world point `p` has view coordinates `x = (p - e).right`, `y = (p - e).up`,
//! `z = (p - e).forward` (`z` is the *depth*: the distance along the viewing axis, as a depth
//! camera reports it). With the focal length in pixels `f = (H / 2) / tan(fov_y / 2)` and the
//! principal point `(c_x, c_y) = (W / 2, H / 2)` the continuous image coordinates are
//!
//! `u = c_x + f x / z`, `v = c_y - f y / z`
//!
//! (`u` to the right, `v` downward; pixel `(i, j)` covers `[i, i+1) x [j, j+1)`, its centre
//! is `(i + 1/2, j + 1/2)`).
//!
//! # Unprojection
//!
//! The inverse for a pixel coordinate `(u, v)` and a depth `z`:
//!
//! `p = e + z (forward + (u - c_x) / f right - (v - c_y) / f up)`.

use super::{add, cross, dot, normalize, scale, sub};

/// A pinhole depth camera looking from `eye` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// position of the eye (centre of projection)
    pub eye: [f64; 3],
    /// the point looked at; it projects to the image centre
    pub target: [f64; 3],
    /// the world direction shown upward in the image (need not be orthogonal to the view
    /// direction)
    pub up: [f64; 3],
    /// vertical field of view in radians, in `(0, pi)`
    pub fov_y: f64,
    /// image width in pixels
    pub width: usize,
    /// image height in pixels
    pub height: usize,
}

/// The camera's orthonormal frame and intrinsics (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    /// the eye
    pub eye: [f64; 3],
    /// image x axis in the world
    pub right: [f64; 3],
    /// image upward axis in the world
    pub up: [f64; 3],
    /// viewing axis (depth direction)
    pub forward: [f64; 3],
    /// focal length in pixels
    pub focal: f64,
    /// principal point, x
    pub cx: f64,
    /// principal point, y
    pub cy: f64,
}

impl Camera {
    /// A `width x height` camera at `eye` looking at `target` with +y up and vertical field
    /// of view `fov_y` (radians).
    pub fn look_at(eye: [f64; 3], target: [f64; 3], fov_y: f64, width: usize, height: usize) -> Self {
        Camera {
            eye,
            target,
            up: [0.0, 1.0, 0.0],
            fov_y,
            width,
            height,
        }
    }

    /// The orthonormal frame and intrinsics.
    pub fn frame(&self) -> CameraFrame {
        let forward = normalize(sub(self.target, self.eye));
        let mut right = normalize(cross(forward, self.up));
        if dot(right, right) < 0.5 {
            // up parallel to the view direction (or zero): any perpendicular will do
            let alt = if forward[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 0.0, 1.0]
            };
            right = normalize(cross(forward, alt));
        }
        let up = cross(right, forward);
        CameraFrame {
            eye: self.eye,
            right,
            up,
            forward,
            focal: 0.5 * self.height as f64 / (0.5 * self.fov_y).tan(),
            cx: 0.5 * self.width as f64,
            cy: 0.5 * self.height as f64,
        }
    }
}

impl CameraFrame {
    /// View coordinates `[x, y, z]` of a world point (`z` = depth along the viewing axis).
    pub fn to_view(&self, p: [f64; 3]) -> [f64; 3] {
        let d = sub(p, self.eye);
        [dot(d, self.right), dot(d, self.up), dot(d, self.forward)]
    }

    /// Continuous image coordinates `[u, v, depth]` of a world point, `None` when it is not
    /// in front of the eye (`depth <= 0`).
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 3]> {
        let [x, y, z] = self.to_view(p);
        (z > 0.0).then(|| [self.cx + self.focal * x / z, self.cy - self.focal * y / z, z])
    }

    /// The world point at image coordinates `(u, v)` and depth `z` (inverse of
    /// [`project`](Self::project)).
    pub fn unproject(&self, u: f64, v: f64, z: f64) -> [f64; 3] {
        let dir = add(
            self.forward,
            add(
                scale(self.right, (u - self.cx) / self.focal),
                scale(self.up, -(v - self.cy) / self.focal),
            ),
        );
        add(self.eye, scale(dir, z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_projects_to_the_centre_and_unprojection_inverts() {
        let cam = Camera::look_at([1.0, 2.0, 3.0], [0.0, 0.5, -0.2], 0.8, 40, 30);
        let f = cam.frame();
        let [u, v, z] = f.project(cam.target).unwrap();
        assert!((u - 20.0).abs() < 1e-12 && (v - 15.0).abs() < 1e-12);
        assert!((z - (1.0f64 + 2.25 + 3.2 * 3.2).sqrt()).abs() < 1e-12);
        for p in [[0.3, 0.1, 0.2], [-0.5, 1.0, 0.7], [0.0, 0.0, 0.0]] {
            let [u, v, z] = f.project(p).unwrap();
            let q = f.unproject(u, v, z);
            assert!((0..3).all(|a| (p[a] - q[a]).abs() < 1e-12), "{p:?} {q:?}");
        }
        assert!(f.project([2.0, 3.5, 6.0]).is_none(), "behind the eye");
    }

    #[test]
    fn frame_is_orthonormal_and_y_is_up() {
        let f = Camera::look_at([3.0, 1.0, 0.0], [0.0, 0.0, 0.0], 0.8, 8, 8).frame();
        for (a, b) in [(f.right, f.up), (f.up, f.forward), (f.right, f.forward)] {
            assert!(dot(a, b).abs() < 1e-12);
        }
        assert!(f.up[1] > 0.9);
        // a point above the target appears in the upper half of the image
        assert!(f.project([0.0, 0.5, 0.0]).unwrap()[1] < 4.0);
        // looking straight down still gives a valid frame
        let g = Camera::look_at([0.0, 3.0, 0.0], [0.0; 3], 0.8, 8, 8).frame();
        assert!((dot(g.right, g.right) - 1.0).abs() < 1e-12 && dot(g.right, g.forward).abs() < 1e-12);
    }
}
