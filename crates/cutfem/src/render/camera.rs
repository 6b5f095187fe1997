//! The one pinhole camera: of every picture ([`super::render`], the counterpart of the
//! thesis' OpenGL camera, sec. 4.5.1) and of the virtual depth sensor (`adjoint::observe`,
//! which adds an image size). Its frame, projection and unprojection.
//!
//! # Frame
//!
//! From the eye `e`, the target `t` and the world up direction `a` (normally +y):
//! `forward = (t - e) / |t - e|`, `right = forward x a / |forward x a|`,
//! `up = right x forward` (an orthonormal, right-handed frame). When `a` is (nearly) parallel
//! to the view direction or zero, so that the normalized `right` is not a unit vector
//! (`|right|^2 < 1/2`), another axis is used instead of `a`: +x, or +z when the view is
//! within about 25 degrees of the x axis.
//!
//! # Projection
//!
//! A world point `p` has view coordinates `x = (p - e).right`, `y = (p - e).up`,
//! `z = (p - e).forward` (`z` is the *depth*: the distance along the viewing axis, as a depth
//! camera reports it). In a `W x H` image, with the focal length in pixels
//! `f = (H / 2) / tan(fov_y / 2)` and the principal point `(c_x, c_y) = (W / 2, H / 2)`, the
//! continuous image coordinates are
//!
//! `u = c_x + f x / z`, `v = c_y - f y / z`
//!
//! (`u` to the right, `v` downward; pixel `(i, j)` covers `[i, i+1) x [j, j+1)`, its centre
//! is `(i + 1/2, j + 1/2)`). Pixels are square, so the horizontal field of view follows from
//! the aspect ratio.
//!
//! # Unprojection
//!
//! The inverse for a pixel coordinate `(u, v)` and a depth `z`:
//!
//! `p = e + z (forward + (u - c_x) / f right - (v - c_y) / f up)`,
//!
//! where the bracket is the ray through `(u, v)` scaled to unit depth ([`CameraFrame::ray`]).
//!
//! # Field of view and near plane
//!
//! `fov_y` is in radians, valid in the open interval `(0, pi)` ([`Camera::is_valid_fov_y`],
//! the one rule every reader of cameras checks); the frame of a camera outside it is
//! meaningless. [`CameraFrame::project`] keeps every point in front of the eye (`z > 0`);
//! a rasterizer cuts at its own near plane `z > near` ([`CameraFrame::project_beyond`]), a
//! fraction of the eye-target distance ([`Camera::distance`]): 1e-3 for the pictures, 1e-6
//! for the depth sensor.

use crate::v3::{add, cross, dot, normalize, scale, sub};

/// Distance of the pictures' near plane from the eye, relative to the eye-target distance.
const PICTURE_NEAR: f64 = 1e-3;

/// The vertical field of view of [`Camera::orbit`] and [`Camera::framing`]: 40 degrees, in
/// radians.
pub const ORBIT_FOV_Y: f64 = 40.0 * (std::f64::consts::PI / 180.0);

/// A pinhole camera looking from `eye` at `target` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// position of the eye (centre of projection)
    pub eye: [f64; 3],
    /// the point looked at; it projects to the image centre
    pub target: [f64; 3],
    /// the world direction shown upward in the image (need not be orthogonal to the view
    /// direction; when parallel to it or zero another axis is used)
    pub up: [f64; 3],
    /// vertical field of view in radians, in `(0, pi)`
    pub fov_y: f64,
}

/// A camera's orthonormal frame and intrinsics for one image size (see the module docs).
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
    /// A camera at `eye` looking at `target` with +y up and vertical field of view `fov_y`
    /// (radians).
    pub fn look_at(eye: [f64; 3], target: [f64; 3], fov_y: f64) -> Self {
        Camera {
            eye,
            target,
            up: [0.0, 1.0, 0.0],
            fov_y,
        }
    }

    /// A camera with the vertical field of view [`ORBIT_FOV_Y`] (40 degrees) at distance
    /// `radius` from `center`, looking at it, y up: `theta` is the azimuth in radians about +y
    /// (0 = on the +z side, pi/2 = on the +x side) and `phi` the elevation in radians above
    /// the xz-plane (|phi| < pi/2).
    pub fn orbit(center: [f64; 3], radius: f64, theta: f64, phi: f64) -> Self {
        let dir = [phi.cos() * theta.sin(), phi.sin(), phi.cos() * theta.cos()];
        Camera::look_at(
            [0, 1, 2].map(|d| center[d] + radius * dir[d]),
            center,
            ORBIT_FOV_Y,
        )
    }

    /// An [`orbit`](Camera::orbit) camera around the box `[min, max]` at the distance where the
    /// box's bounding sphere just fits the vertical field of view (with a 5 % margin).
    pub fn framing(min: [f64; 3], max: [f64; 3], theta: f64, phi: f64) -> Self {
        let center = [0, 1, 2].map(|d| 0.5 * (min[d] + max[d]));
        let r = 0.5 * dot(sub(max, min), sub(max, min)).sqrt();
        let half = 0.5 * ORBIT_FOV_Y;
        let dist = (1.05 * r / half.sin()).max(1e-9);
        Camera::orbit(center, dist, theta, phi)
    }

    /// Whether `fov_y` is a valid vertical field of view: finite, in `(0, pi)` radians (the
    /// one rule; readers of cameras word their own errors).
    pub fn is_valid_fov_y(fov_y: f64) -> bool {
        fov_y.is_finite() && fov_y > 0.0 && fov_y < std::f64::consts::PI
    }

    /// The eye-target distance (the scale of the near planes).
    pub fn distance(&self) -> f64 {
        let view = sub(self.target, self.eye);
        dot(view, view).sqrt()
    }

    /// The frame and intrinsics of a `width x height` image (see the module docs).
    pub fn frame(&self, width: usize, height: usize) -> CameraFrame {
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
            focal: 0.5 * height as f64 / (0.5 * self.fov_y).tan(),
            cx: 0.5 * width as f64,
            cy: 0.5 * height as f64,
        }
    }

    /// The direction towards the headlight, just above and left of the eye (the light of
    /// every picture).
    pub fn headlight(&self) -> [f64; 3] {
        let fr = self.frame(1, 1);
        normalize([0, 1, 2].map(|d| -fr.forward[d] + 0.35 * fr.up[d] - 0.25 * fr.right[d]))
    }

    /// The near plane of the pictures: depth 1e-3 times the eye-target distance.
    pub(crate) fn picture_near(&self) -> f64 {
        PICTURE_NEAR * self.distance().max(1e-12)
    }

    /// Projects world point `p` into a `width` x `height` picture: `[x, y, depth]` with pixel
    /// coordinates (x to the right, y downward, pixel centres at half-integers) and the depth
    /// along the view direction; `None` when `p` is not in front of the pictures' near plane.
    pub fn project(&self, p: [f64; 3], width: usize, height: usize) -> Option<[f64; 3]> {
        self.frame(width, height).project_beyond(p, self.picture_near())
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
        self.project_beyond(p, 0.0)
    }

    /// [`project`](Self::project), `None` unless the depth is beyond `near` (and not NaN).
    pub fn project_beyond(&self, p: [f64; 3], near: f64) -> Option<[f64; 3]> {
        let [x, y, z] = self.to_view(p);
        (z > near).then(|| [self.cx + self.focal * x / z, self.cy - self.focal * y / z, z])
    }

    /// The direction of the ray through image coordinates `(u, v)`, scaled to unit depth:
    /// `forward + (u - c_x) / f right - (v - c_y) / f up`.
    pub fn ray(&self, u: f64, v: f64) -> [f64; 3] {
        add(
            self.forward,
            add(
                scale(self.right, (u - self.cx) / self.focal),
                scale(self.up, -(v - self.cy) / self.focal),
            ),
        )
    }

    /// The world point at image coordinates `(u, v)` and depth `z` (inverse of
    /// [`project`](Self::project)).
    pub fn unproject(&self, u: f64, v: f64, z: f64) -> [f64; 3] {
        add(self.eye, scale(self.ray(u, v), z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_projects_to_the_centre_and_unprojection_inverts() {
        let cam = Camera::look_at([1.0, 2.0, 3.0], [0.0, 0.5, -0.2], 0.8);
        let f = cam.frame(40, 30);
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
        let f = Camera::look_at([3.0, 1.0, 0.0], [0.0, 0.0, 0.0], 0.8).frame(8, 8);
        for (a, b) in [(f.right, f.up), (f.up, f.forward), (f.right, f.forward)] {
            assert!(dot(a, b).abs() < 1e-12);
        }
        assert!(f.up[1] > 0.9);
        // a point above the target appears in the upper half of the image
        assert!(f.project([0.0, 0.5, 0.0]).unwrap()[1] < 4.0);
        // looking straight down still gives a valid frame
        let g = Camera::look_at([0.0, 3.0, 0.0], [0.0; 3], 0.8).frame(8, 8);
        assert!((dot(g.right, g.right) - 1.0).abs() < 1e-12 && dot(g.right, g.forward).abs() < 1e-12);
    }

    /// The near planes, the field-of-view rule, and the orbit cameras' 40 degrees.
    #[test]
    fn near_planes_fov_rule_and_orbit() {
        assert_eq!(ORBIT_FOV_Y, 40f64.to_radians());
        assert_eq!(0.5 * ORBIT_FOV_Y, 20f64.to_radians());
        let cam = Camera::orbit([0.0; 3], 2.0, 0.3, 0.2);
        assert_eq!(cam.fov_y, ORBIT_FOV_Y);
        assert!((cam.distance() - 2.0).abs() < 1e-12);
        let f = cam.frame(64, 48);
        // a point just behind the pictures' near plane projects for the sensor, not the picture
        let p = add(cam.eye, scale(f.forward, 1e-4));
        assert!(f.project(p).is_some() && cam.project(p, 64, 48).is_none());
        assert!(f.project_beyond([f64::NAN; 3], 0.0).is_none());
        for ok in [1e-6, 0.8, 3.1] {
            assert!(Camera::is_valid_fov_y(ok), "{ok}");
        }
        for bad in [0.0, -0.1, std::f64::consts::PI, 4.0, f64::NAN, f64::INFINITY] {
            assert!(!Camera::is_valid_fov_y(bad), "{bad}");
        }
    }
}
