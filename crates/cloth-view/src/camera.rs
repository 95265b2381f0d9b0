//! An orbit camera: drag to orbit, right/middle-drag to pan, scroll to zoom.

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

/// Orbit camera around a target point (angles in radians, distances in m).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OrbitCamera {
    /// Point looked at, m.
    pub target: [f32; 3],
    /// Angle around the vertical axis, rad.
    pub yaw: f32,
    /// Angle above the horizontal, rad.
    pub pitch: f32,
    /// Distance from the target, m.
    pub distance: f32,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        Self { target: [0.0, 0.9, 0.0], yaw: 0.6, pitch: 0.35, distance: 4.2 }
    }
}

impl OrbitCamera {
    /// Eye position, m.
    pub fn eye(&self) -> Vec3 {
        let dir = Vec3::new(self.pitch.cos() * self.yaw.sin(), self.pitch.sin(), self.pitch.cos() * self.yaw.cos());
        Vec3::from(self.target) + dir * self.distance
    }

    /// World-to-clip matrix for an aspect ratio (width / height).
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let view = Mat4::look_at_rh(self.eye(), Vec3::from(self.target), Vec3::Y);
        let proj = Mat4::perspective_rh(45f32.to_radians(), aspect.max(0.1), 0.05, 200.0);
        proj * view
    }

    /// Camera right and up vectors (for panning and dragging in the view plane).
    pub fn right_up(&self) -> (Vec3, Vec3) {
        let forward = (Vec3::from(self.target) - self.eye()).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        (right, right.cross(forward))
    }

    /// Orbits by a mouse drag of `(dx, dy)` points.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * 0.008;
        self.pitch = (self.pitch + dy * 0.008).clamp(-1.5, 1.5);
    }

    /// Pans by a mouse drag of `(dx, dy)` points.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let (right, up) = self.right_up();
        let scale = self.distance * 0.0015;
        let t = Vec3::from(self.target) - right * dx * scale + up * dy * scale;
        self.target = t.into();
    }

    /// Zooms by a scroll of `delta` points.
    pub fn zoom(&mut self, delta: f32) {
        self.distance = (self.distance * (-delta * 0.002).exp()).clamp(0.2, 100.0);
    }
}
