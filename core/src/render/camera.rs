//! The view: a pinhole or an orthographic camera, from a scene file's camera, from explicit
//! from/to/fov, or framed from the asset's bounds; turntables orbit it around the up axis
//! through the look-at point.

pub use crate::mesh::Projection;
use crate::mesh::{SceneCamera, UpAxis};
use crate::trace::Ray;
use glam::{Quat, Vec2, Vec3};

/// The widest vertical field of view a camera may have, degrees (exclusive).
pub const MAX_FOV_DEG: f32 = 179.0;

/// Whether a vertical field of view (degrees) gives a usable picture: above 0 (all rays one
/// way, or the picture turned over below it) and below `MAX_FOV_DEG` (folded past 180°). What
/// `--fov` and a scene file's camera must both meet.
pub fn usable_fov(deg: f32) -> bool {
    deg > 0.0 && deg < MAX_FOV_DEG
}

/// The eight corners of the box `lo`–`hi` (corner `i` takes `hi` on the axes of its set bits:
/// x 1, y 2, z 4).
pub fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// The box's corners as a camera sees them on each frame of a `turns`-frame turntable that
/// orbits it about `axis` through `pivot` (the corners turned the other way; 1: as they are).
fn turned_corners(lo: Vec3, hi: Vec3, pivot: Vec3, axis: Vec3, turns: u32) -> Vec<Vec3> {
    let corners = box_corners(lo, hi);
    (0..turns.max(1))
        .flat_map(|k| {
            let angle = super::job::turntable_angle(k, turns);
            let rot = Quat::from_axis_angle(axis.normalize(), -angle);
            corners.map(|c| pivot + rot * (c - pivot))
        })
        .collect()
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub from: Vec3,
    pub to: Vec3,
    pub up: Vec3,
    pub projection: Projection,
}

impl Camera {
    /// The scene camera for an image of `aspect` (width over height): an image narrower than
    /// its film back (`SceneCamera::film_aspect`) gets a taller view, so that the film back's
    /// whole width stays in it (USD's `expandAperture`); a view sized along the larger side
    /// (`SceneCamera::larger_side`) is that much less tall in a landscape image.
    pub fn from_scene(c: &SceneCamera, aspect: f32) -> Self {
        let widen = c.film_aspect.map_or(1.0, |film| (film / aspect).max(1.0));
        Camera {
            from: c.from,
            to: c.to,
            up: c.up,
            projection: match c.projection {
                Projection::Perspective { yfov_deg } => Projection::Perspective {
                    yfov_deg: match widen > 1.0 {
                        true => (2.0 * ((0.5 * yfov_deg).to_radians().tan() * widen).atan())
                            .to_degrees(),
                        false => yfov_deg,
                    },
                },
                Projection::Orthographic { height } => Projection::Orthographic {
                    height: match c.larger_side {
                        true => height * widen * (1.0 / aspect).min(1.0),
                        false => height * widen,
                    },
                },
            },
        }
    }

    /// A pinhole camera with vertical field of view `yfov_deg`.
    pub fn perspective(from: Vec3, to: Vec3, up: Vec3, yfov_deg: f32) -> Self {
        Camera {
            from,
            to,
            up,
            projection: Projection::Perspective { yfov_deg },
        }
    }

    /// The height an orthographic view from this camera's place needs to hold the box
    /// `lo`–`hi` (all eight corners, with a 10% margin, at image aspect `aspect`), and the
    /// camera moved back along its view, where needed, so that the box lies ahead of it (an
    /// orthographic ray starts on the plane through the camera).
    pub fn fit_orthographic(&self, lo: Vec3, hi: Vec3, aspect: f32) -> Self {
        self.fit_orthographic_turning(lo, hi, aspect, Vec3::Y, 1)
    }

    /// `fit_orthographic` for every frame of a `turns`-frame turntable that orbits this camera
    /// about `axis` through its look-at point: the one view holds the box on all of them.
    pub fn fit_orthographic_turning(
        &self,
        lo: Vec3,
        hi: Vec3,
        aspect: f32,
        axis: Vec3,
        turns: u32,
    ) -> Self {
        let (right, up, back) = self.basis();
        let (mut half, mut ahead) = (0.0f32, f32::INFINITY);
        for corner in turned_corners(lo, hi, self.to, axis, turns) {
            let corner = corner - self.from;
            half = half
                .max(corner.dot(up).abs())
                .max(corner.dot(right).abs() / aspect);
            ahead = ahead.min(-corner.dot(back));
        }
        let margin = 0.1 * (hi - lo).length();
        let pull = (margin - ahead).max(0.0);
        Camera {
            from: self.from + back * pull,
            to: self.to + back * pull,
            projection: Projection::Orthographic {
                height: (2.2 * half).max(f32::MIN_POSITIVE),
            },
            ..*self
        }
    }

    /// Look at the centre of the bounds from the front, a little above, just far enough that
    /// all eight box corners are inside the view (with a 10% margin) for this aspect ratio.
    pub fn frame_bounds(lo: Vec3, hi: Vec3, up_axis: UpAxis, yfov_deg: f32, aspect: f32) -> Self {
        Self::frame_bounds_turning(lo, hi, up_axis, yfov_deg, aspect, 1)
    }

    /// `frame_bounds` for every frame of a `turns`-frame turntable, which orbits the camera
    /// about the up axis through the box's centre: far enough back that the box is in view
    /// on all of them (a box long from front to back, seen end on in frame 0, fills the view
    /// side on a quarter turn later).
    pub fn frame_bounds_turning(
        lo: Vec3,
        hi: Vec3,
        up_axis: UpAxis,
        yfov_deg: f32,
        aspect: f32,
        turns: u32,
    ) -> Self {
        let centre = (lo + hi) * 0.5;
        let (up, front) = match up_axis {
            UpAxis::Y => (Vec3::Y, Vec3::Z),
            UpAxis::Z => (Vec3::Z, -Vec3::Y),
        };
        let dir = (front + up * 0.35).normalize();
        let mut cam = Camera::perspective(centre + dir, centre, up, yfov_deg);
        let (right, cam_up, back) = cam.basis();
        let tan_y = (yfov_deg.to_radians() * 0.5).tan() / 1.1;
        let tan_x = tan_y * aspect;
        let mut dist = 1e-6f32;
        for corner in turned_corners(lo, hi, centre, up, turns) {
            let corner = corner - centre;
            let z = corner.dot(back);
            dist = dist
                .max(z + corner.dot(right).abs() / tan_x)
                .max(z + corner.dot(cam_up).abs() / tan_y);
        }
        cam.from = centre + dir * dist;
        cam
    }

    /// The camera orbited by `angle` radians about the axis `axis` through the look-at point
    /// (counter-clockwise seen from where `axis` points): its position and its own up turn
    /// together, so a camera pitched towards the asset (a scene camera whose up leans off the
    /// asset's) keeps its height and pitch all the way round.
    pub fn orbit(&self, axis: Vec3, angle: f32) -> Self {
        if angle == 0.0 {
            return *self;
        }
        let rot = Quat::from_axis_angle(axis.normalize(), angle);
        Camera {
            from: self.to + rot * (self.from - self.to),
            up: rot * self.up,
            ..*self
        }
    }

    /// Orthonormal basis (right, up, back) of the view.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let back = (self.from - self.to).normalize();
        let mut right = self.up.cross(back);
        if right.length_squared() < 1e-12 {
            right = back.any_orthonormal_vector();
        }
        let right = right.normalize();
        (right, back.cross(right), back)
    }

    /// The ray through image position `p` in pixels (origin top-left) of a `w`×`h` image.
    pub fn ray(&self, p: Vec2, w: u32, h: u32) -> Ray {
        self.raster(w, h).ray(p)
    }

    /// The view set up once for a `w`×`h` image: `Raster::ray` per pixel then skips the basis
    /// (two normalisations, a cross product) and the field of view's tangent that every ray
    /// shares.
    pub fn raster(&self, w: u32, h: u32) -> Raster {
        let (right, up, back) = self.basis();
        let (half, orthographic) = self.half_extent();
        Raster {
            from: self.from,
            right,
            up,
            back,
            half,
            orthographic,
            aspect: w as f32 / h as f32,
            w: w as f32,
            h: h as f32,
        }
    }

    /// Half the view's height: at unit distance for a pinhole (the tangent of half its field
    /// of view), in scene units for an orthographic view (then `true`).
    pub fn half_extent(&self) -> (f32, bool) {
        match self.projection {
            Projection::Perspective { yfov_deg } => ((yfov_deg.to_radians() * 0.5).tan(), false),
            Projection::Orthographic { height } => (0.5 * height, true),
        }
    }
}

/// A camera's rays for one image size (`Camera::raster`).
#[derive(Clone, Copy, Debug)]
pub struct Raster {
    from: Vec3,
    right: Vec3,
    up: Vec3,
    back: Vec3,
    /// `Camera::half_extent`.
    half: f32,
    orthographic: bool,
    aspect: f32,
    w: f32,
    h: f32,
}

impl Raster {
    /// The ray through image position `p` in pixels (origin top-left): from the camera
    /// through the image plane at unit distance, or, orthographic, from that position on the
    /// plane through the camera, along the view.
    #[inline]
    pub fn ray(&self, p: Vec2) -> Ray {
        let x = (2.0 * p.x / self.w - 1.0) * self.half * self.aspect;
        let y = (1.0 - 2.0 * p.y / self.h) * self.half;
        let offset = self.right * x + self.up * y;
        match self.orthographic {
            true => Ray::new(self.from + offset, -self.back),
            false => Ray::new(self.from, (offset - self.back).normalize()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_turntable_orbits() {
        let c = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0);
        let r = c.ray(Vec2::new(50.0, 50.0), 100, 100);
        assert!((r.dir - -Vec3::Z).length() < 1e-6);
        let q = c.orbit(Vec3::Y, std::f32::consts::FRAC_PI_2);
        assert!(
            (q.from - Vec3::new(5.0, 0.0, 0.0)).length() < 1e-4,
            "{:?}",
            q.from
        );
        // Top of the image looks up.
        assert!(c.ray(Vec2::new(50.0, 0.0), 100, 100).dir.y > 0.0);
    }

    /// A scene camera pitched down at the asset has an up that leans off the asset's: the
    /// orbit is about the asset's up, so the camera keeps its height and its pitch, and its
    /// up turns with it (an orbit about the camera's own up would wobble the asset).
    #[test]
    fn a_pitched_camera_orbits_the_assets_up_axis_at_its_own_height() {
        let from = Vec3::new(0.0, 3.0, 4.0);
        let back = from.normalize();
        let right = Vec3::Y.cross(back).normalize();
        let c = Camera::perspective(from, Vec3::ZERO, back.cross(right), 40.0);
        assert!(c.up.y < 0.9, "the camera's up leans: {}", c.up);
        let centre = |c: &Camera| c.ray(Vec2::new(50.0, 50.0), 100, 100).dir;
        for k in 1..8 {
            let q = c.orbit(Vec3::Y, std::f32::consts::TAU * k as f32 / 8.0);
            assert!((q.from.y - 3.0).abs() < 1e-4, "frame {k}: {}", q.from);
            assert!(
                (q.from.length() - 5.0).abs() < 1e-4,
                "frame {k}: {}",
                q.from
            );
            assert!(
                (centre(&q).y - centre(&c).y).abs() < 1e-5,
                "frame {k}: pitch"
            );
            assert!((q.up.y - c.up.y).abs() < 1e-5, "frame {k}: up {}", q.up);
            assert!(
                q.up.dot(q.from - q.to).abs() < 1e-4,
                "frame {k}: up off the view"
            );
        }
    }

    /// Orthographic rays are parallel to the view and start on the plane through the camera,
    /// spread over the view's height (and its width at the image's aspect); a pinhole's
    /// arithmetic is unchanged (the GPU mirrors both).
    #[test]
    fn orthographic_rays_are_parallel_and_span_the_views_height() {
        let c = Camera {
            projection: Projection::Orthographic { height: 3.0 },
            ..Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0)
        };
        let (w, h) = (200, 100);
        let centre = c.ray(Vec2::new(100.0, 50.0), w, h);
        assert_eq!((centre.origin, centre.dir), (c.from, Vec3::NEG_Z));
        let corner = c.ray(Vec2::new(0.0, 0.0), w, h);
        assert_eq!(corner.dir, Vec3::NEG_Z);
        assert!((corner.origin - Vec3::new(-3.0, 1.5, 5.0)).length() < 1e-6);
        let bottom = c.ray(Vec2::new(200.0, 100.0), w, h);
        assert!((bottom.origin - Vec3::new(3.0, -1.5, 5.0)).length() < 1e-6);
    }

    /// `--ortho fit`: every corner of the box inside the view with the 10% margin, whatever
    /// the aspect, and ahead of the plane the rays start from, even from a camera placed
    /// inside the box (moved back along its view, still looking the same way).
    #[test]
    fn an_orthographic_fit_holds_the_bounds_ahead_of_the_camera() {
        let (lo, hi) = (Vec3::new(-1.0, -0.2, -3.0), Vec3::new(1.0, 0.2, 3.0));
        for from in [Vec3::new(0.5, 2.0, 6.0), Vec3::new(0.0, 0.0, 1.0)] {
            for aspect in [1.0f32, 2.0, 0.5] {
                let start = Camera::perspective(from, Vec3::ZERO, Vec3::Y, 40.0);
                let c = start.fit_orthographic(lo, hi, aspect);
                let Projection::Orthographic { height } = c.projection else {
                    panic!("{c:?}");
                };
                assert_eq!(c.basis(), start.basis(), "the view turned");
                let (right, up, back) = c.basis();
                for (i, corner) in box_corners(lo, hi).into_iter().enumerate() {
                    let p = corner - c.from;
                    assert!(-p.dot(back) > 0.0, "{from} corner {i} behind the camera");
                    let x = p.dot(right) / (0.5 * height * aspect);
                    let y = p.dot(up) / (0.5 * height);
                    assert!(
                        x.abs() <= 1.0 / 1.1 + 1e-4 && y.abs() <= 1.0 / 1.1 + 1e-4,
                        "{from} aspect {aspect} corner {i}: {x} {y}"
                    );
                }
            }
        }
    }

    #[test]
    fn framing_contains_the_bounds() {
        // Every corner of the box projects inside the image (with the 10% margin) for a wide
        // and a tall image; breaks if the framing ignores the aspect ratio or a corner.
        let (lo, hi) = (Vec3::new(-1.0, -0.2, -3.0), Vec3::new(1.0, 0.2, 3.0));
        for aspect in [1.0f32, 2.0, 0.5] {
            let c = Camera::frame_bounds(lo, hi, UpAxis::Y, 40.0, aspect);
            let (right, up, back) = c.basis();
            let tan_y = (20f32).to_radians().tan();
            for (i, corner) in box_corners(lo, hi).into_iter().enumerate() {
                let p = corner - c.from;
                let depth = -p.dot(back);
                assert!(depth > 0.0);
                let x = p.dot(right) / (depth * tan_y * aspect);
                let y = p.dot(up) / (depth * tan_y);
                assert!(
                    x.abs() <= 1.0 / 1.1 + 1e-4 && y.abs() <= 1.0 / 1.1 + 1e-4,
                    "aspect {aspect} corner {i}: {x} {y}"
                );
            }
        }
    }
}
