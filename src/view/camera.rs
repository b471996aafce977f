//! Cameras framed from an asset's bounds, so that any asset — a 0.2 m bunny or a 500 m field —
//! fills the picture without per-asset tuning.
//!
//! A camera orbits the centre of the bounding sphere of what is drawn (morph-extruded extents
//! included, see `glb::Asset::bounds`). `yaw` turns about +Y (0° looks from +Z towards −Z, 90°
//! from +X), `pitch` raises the eye, and `distance` is in multiples of the bounding radius `R`.
//! The named views are fixed points of that orbit:
//!
//! | view | yaw | pitch | distance | vertical FOV | shows |
//! |---|---|---|---|---|---|
//! | `front` | 0° | 20° | fit | 35° | the whole asset |
//! | `side` | 90° | 0° | fit | 35° | the silhouette, where shells are seen edge-on |
//! | `top` | 0° | 89° | fit | 35° | the asset from above |
//! | `close` | 30° | 30° | 1.6 R | 20° | a few dozen strands near the surface facing the eye |
//! | `far` | 0° | 20° | 8 R | 35° | the asset small, where alpha-tested strands alias |
//!
//! "fit" is the distance at which the bounding sphere touches the narrower field of view
//! (`R / sin(fov/2)`), times 1.02. The near and far planes hug the sphere so a 32-bit depth
//! buffer keeps its precision at any scale.
//!
//! Positions are kept in `f64` until the renderer subtracts the [`Camera::anchor`] (the sphere
//! centre): everything the GPU sees is relative to that anchor, so assets far from the origin
//! draw without jitter. [`Camera::view_matrix`] and [`Camera::projection`] give the matrices in
//! world space for other renderers (three.js) to be placed at the same camera; `projection` uses
//! wgpu's [0, 1] depth range, [`Camera::projection_gl`] OpenGL's [−1, 1].

use glam::{DMat4, DVec3, DVec4, Mat4, Vec3};

/// A named camera position (see the module table).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NamedView {
    Front,
    Side,
    Top,
    Close,
    Far,
}

impl NamedView {
    pub const ALL: [NamedView; 5] = [
        NamedView::Front,
        NamedView::Side,
        NamedView::Top,
        NamedView::Close,
        NamedView::Far,
    ];

    pub fn name(self) -> &'static str {
        match self {
            NamedView::Front => "front",
            NamedView::Side => "side",
            NamedView::Top => "top",
            NamedView::Close => "close",
            NamedView::Far => "far",
        }
    }

    /// The orbit parameters of this view.
    pub fn orbit(self) -> Orbit {
        let fit = Orbit {
            yaw_deg: 0.0,
            pitch_deg: 20.0,
            distance: None,
            fov_y_deg: 35.0,
        };
        match self {
            NamedView::Front => fit,
            NamedView::Side => Orbit {
                yaw_deg: 90.0,
                pitch_deg: 0.0,
                ..fit
            },
            NamedView::Top => Orbit {
                pitch_deg: 89.0,
                ..fit
            },
            NamedView::Close => Orbit {
                yaw_deg: 30.0,
                pitch_deg: 30.0,
                distance: Some(1.6),
                fov_y_deg: 20.0,
            },
            NamedView::Far => Orbit {
                distance: Some(8.0),
                ..fit
            },
        }
    }
}

/// A point on the orbit around the bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    pub yaw_deg: f64,
    pub pitch_deg: f64,
    /// Eye distance from the centre in bounding radii; `None` fits the sphere to the view.
    pub distance: Option<f64>,
    pub fov_y_deg: f64,
}

impl Orbit {
    /// Unit vector from the orbit's centre towards the eye.
    pub fn direction(&self) -> DVec3 {
        let (yaw, pitch) = (self.yaw_deg.to_radians(), self.pitch_deg.to_radians());
        DVec3::new(
            yaw.sin() * pitch.cos(),
            pitch.sin(),
            yaw.cos() * pitch.cos(),
        )
    }
}

impl Default for Orbit {
    fn default() -> Self {
        NamedView::Front.orbit()
    }
}

/// A bounding sphere in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: DVec3,
    pub radius: f64,
}

impl Sphere {
    /// The sphere around an axis-aligned box (never of zero radius).
    pub fn around_box(lo: DVec3, hi: DVec3) -> Sphere {
        let r = (hi - lo).length() * 0.5;
        Sphere {
            center: (lo + hi) * 0.5,
            radius: if r > 0.0 && r.is_finite() { r } else { 1.0 },
        }
    }
}

/// A perspective camera in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    pub fov_y_deg: f64,
    /// Width / height.
    pub aspect: f64,
    pub near: f64,
    pub far: f64,
}

impl Camera {
    /// The camera at `orbit` around `sphere` for a picture of `aspect` = width / height.
    pub fn frame(sphere: Sphere, orbit: Orbit, aspect: f64) -> Camera {
        let r = sphere.radius;
        let half_y = orbit.fov_y_deg.to_radians() * 0.5;
        let half_x = (half_y.tan() * aspect).atan();
        let half = half_y.min(half_x);
        let d = orbit.distance.map_or(1.02 / half.sin(), |d| d.max(1e-3)) * r;
        let dir = orbit.direction();
        let near = (d - 1.05 * r).max(d * 1e-3);
        Camera {
            eye: sphere.center + dir * d,
            target: sphere.center,
            up: DVec3::Y,
            fov_y_deg: orbit.fov_y_deg,
            aspect,
            near,
            far: d + 1.05 * r,
        }
    }

    /// The point every GPU coordinate is made relative to.
    pub fn anchor(&self) -> DVec3 {
        self.target
    }

    /// World → view (right-handed, looking down −Z).
    pub fn view_matrix(&self) -> DMat4 {
        look_at(self.eye, self.target, self.up)
    }

    /// View → clip, depth in [0, 1] (wgpu, WebGPU, Vulkan).
    pub fn projection(&self) -> DMat4 {
        let (f, n, z) = (
            1.0 / (self.fov_y_deg.to_radians() * 0.5).tan(),
            self.near,
            self.far,
        );
        DMat4::from_cols(
            DVec4::new(f / self.aspect, 0.0, 0.0, 0.0),
            DVec4::new(0.0, f, 0.0, 0.0),
            DVec4::new(0.0, 0.0, z / (n - z), -1.0),
            DVec4::new(0.0, 0.0, n * z / (n - z), 0.0),
        )
    }

    /// View → clip, depth in [−1, 1] (OpenGL, WebGL, three.js).
    pub fn projection_gl(&self) -> DMat4 {
        let (f, n, z) = (
            1.0 / (self.fov_y_deg.to_radians() * 0.5).tan(),
            self.near,
            self.far,
        );
        DMat4::from_cols(
            DVec4::new(f / self.aspect, 0.0, 0.0, 0.0),
            DVec4::new(0.0, f, 0.0, 0.0),
            DVec4::new(0.0, 0.0, (z + n) / (n - z), -1.0),
            DVec4::new(0.0, 0.0, 2.0 * n * z / (n - z), 0.0),
        )
    }

    /// Anchor-relative view-projection for the GPU.
    pub fn gpu_view_projection(&self) -> Mat4 {
        let a = self.anchor();
        let view = look_at(self.eye - a, self.target - a, self.up);
        (self.projection() * view).as_mat4()
    }

    /// Anchor-relative eye position for the GPU.
    pub fn gpu_eye(&self) -> Vec3 {
        (self.eye - self.anchor()).as_vec3()
    }
}

/// Right-handed look-at: the eye at the origin looking down −Z, `up` towards +Y.
fn look_at(eye: DVec3, target: DVec3, up: DVec3) -> DMat4 {
    let f = (target - eye).normalize();
    let s = f.cross(up).try_normalize().unwrap_or(DVec3::X);
    let u = s.cross(f);
    DMat4::from_cols(
        DVec4::new(s.x, u.x, -f.x, 0.0),
        DVec4::new(s.y, u.y, -f.y, 0.0),
        DVec4::new(s.z, u.z, -f.z, 0.0),
        DVec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_keeps_the_sphere_inside_the_frustum() {
        let s = Sphere {
            center: DVec3::new(1e6, 0.0, -3.0),
            radius: 2.0,
        };
        for v in NamedView::ALL {
            for aspect in [0.5, 1.0, 2.0] {
                let c = Camera::frame(s, v.orbit(), aspect);
                let clip = c.projection() * c.view_matrix();
                // the centre projects to the middle of the picture, in front of the camera
                let p = clip.project_point3(s.center);
                assert!(
                    p.x.abs() < 1e-9 && p.y.abs() < 1e-9 && p.z > 0.0 && p.z < 1.0,
                    "{v:?} {p}"
                );
                if v.orbit().distance.is_none() {
                    // points of the sphere stay inside [-1, 1]
                    for d in [
                        DVec3::X,
                        DVec3::Y,
                        DVec3::Z,
                        -DVec3::X,
                        -DVec3::Y,
                        -DVec3::Z,
                    ] {
                        let q = clip.project_point3(s.center + d * s.radius);
                        assert!(
                            q.x.abs() <= 1.0 && q.y.abs() <= 1.0 && q.z >= 0.0 && q.z <= 1.0,
                            "{v:?} {q}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn gpu_matrices_are_the_world_matrices_moved_to_the_anchor() {
        let s = Sphere {
            center: DVec3::new(5.0, 1.0, 2.0),
            radius: 1.0,
        };
        let c = Camera::frame(s, NamedView::Close.orbit(), 1.0);
        let world = (c.projection() * c.view_matrix()).project_point3(DVec3::new(5.5, 1.2, 2.1));
        let gpu = c
            .gpu_view_projection()
            .project_point3(Vec3::new(0.5, 0.2, 0.1));
        assert!((world.as_vec3() - gpu).length() < 1e-5);
    }
}
