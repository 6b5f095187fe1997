//! The virtual depth sensor's camera: the workspace's one pinhole camera
//! ([`cutfem::render::Camera`], whose module `cutfem::render::camera` documents the frame,
//! the projection `u = c_x + f x / z`, `v = c_y - f y / z` and the unprojection) plus the
//! size of its depth images.

use cutfem::render::{Camera, CameraFrame};

/// A pinhole depth camera: where it looks from and to, its field of view, and its image size.
///
/// The size lives beside the camera rather than in it because a picture of the same camera
/// may be drawn at any size (the diagnosis renders at its own resolution); a depth sensor has
/// one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthCamera {
    /// the pinhole camera (eye, target, up, vertical field of view in radians)
    pub camera: Camera,
    /// image width in pixels
    pub width: usize,
    /// image height in pixels
    pub height: usize,
}

impl DepthCamera {
    /// A `width x height` camera at `eye` looking at `target` with +y up and vertical field
    /// of view `fov_y` (radians).
    pub fn look_at(eye: [f64; 3], target: [f64; 3], fov_y: f64, width: usize, height: usize) -> Self {
        DepthCamera {
            camera: Camera::look_at(eye, target, fov_y),
            width,
            height,
        }
    }

    /// The orthonormal frame and intrinsics of the camera's images.
    pub fn frame(&self) -> CameraFrame {
        self.camera.frame(self.width, self.height)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_is_the_cameras_at_the_image_size() {
        let cam = DepthCamera::look_at([1.0, 2.0, 3.0], [0.0, 0.5, -0.2], 0.8, 40, 30);
        assert_eq!(cam.frame(), cam.camera.frame(40, 30));
        let [u, v, _] = cam.frame().project(cam.camera.target).unwrap();
        assert!((u - 20.0).abs() < 1e-12 && (v - 15.0).abs() < 1e-12);
    }
}
