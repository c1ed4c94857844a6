//! Euler–Bernoulli cantilever formulas (the corrected paper eq. (21)).
//!
//! A straight uniform beam along its x axis, clamped at s = 0, free at s = L. Its tip moves
//! by the 6-vector `[Δx, Δy, Δz, Δα, Δβ, Δγ]` in the beam frame: translation, then the small
//! rotation vector of the tip section (α about x, β about y, γ about z). Every sign follows from
//! the right-hand rule: a moment about +y turns the tip about +y, which moves it along −z.
//! Derivation and the comparison with eq. (21): `docs/flexibility.md`.

use super::stiffness::LinkStiffness;
use crate::math::Vec3;
use nalgebra::Vector6;

/// Reciprocals of a beam's rigidities: what the formulas multiply by (0 = rigid).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamCompliance {
    /// 1/EA, 1/N.
    pub axial: f64,
    /// 1/EI_y (bending about y, deflection along z), 1/(N·m²).
    pub bending_y: f64,
    /// 1/EI_z (bending about z, deflection along y), 1/(N·m²).
    pub bending_z: f64,
    /// 1/GI_p (torsion about x), 1/(N·m²).
    pub torsion: f64,
}

impl BeamCompliance {
    /// The compliances of `stiffness` (an infinite rigidity gives 0).
    pub fn from_stiffness(stiffness: &LinkStiffness) -> Self {
        Self {
            axial: stiffness.axial.recip(),
            bending_y: stiffness.bending_y.recip(),
            bending_z: stiffness.bending_z.recip(),
            torsion: stiffness.torsion.recip(),
        }
    }

    /// Every compliance times `factor`.
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            axial: self.axial * factor,
            bending_y: self.bending_y * factor,
            bending_z: self.bending_z * factor,
            torsion: self.torsion * factor,
        }
    }
}

/// Tip deflection of a cantilever of length `length` under a force `force` and a moment
/// `moment` (beam frame, N and N·m) applied at distance `station` ∈ [0, L] from the clamp.
///
/// With a = station (a = L is the paper's tip load f, τ):
/// ```text
/// Δx = Fx a / EA                         Δα = Mx a / GI_p
/// Δy = Fy a²(3L − a)/6EI_z + Mz a(2L − a)/2EI_z     Δγ = Fy a²/2EI_z + Mz a/EI_z
/// Δz = Fz a²(3L − a)/6EI_y − My a(2L − a)/2EI_y     Δβ = −Fz a²/2EI_y + My a/EI_y
/// ```
pub fn point_load_deflection(
    length: f64,
    compliance: &BeamCompliance,
    station: f64,
    force: &Vec3,
    moment: &Vec3,
) -> Vector6<f64> {
    let a = station.clamp(0.0, length);
    let (cy, cz) = (compliance.bending_y, compliance.bending_z);
    // Deflection per unit force and per unit moment at the tip, for a load at station a.
    let by_force = a * a * (3.0 * length - a) / 6.0;
    let by_moment = a * (2.0 * length - a) / 2.0;
    let turn_by_force = a * a / 2.0;
    Vector6::new(
        force.x * a * compliance.axial,
        cz * (force.y * by_force + moment.z * by_moment),
        cy * (force.z * by_force - moment.y * by_moment),
        moment.x * a * compliance.torsion,
        cy * (-force.z * turn_by_force + moment.y * a),
        cz * (force.y * turn_by_force + moment.z * a),
    )
}

/// The change of [`point_load_deflection`] when the length, the station, the force and the
/// moment change by `d_length`, `d_station`, `d_force` and `d_moment` (first order; the
/// station is the clamped one and `d_station` its change, which the caller decides at a
/// clamp). Its partial derivatives (docs/flexibility.md §11): `∂(a²(3L − a)/6) = a²/2·dL +
/// (aL − a²/2)·da`, `∂(a(2L − a)/2) = a·dL + (L − a)·da`, `∂(a²/2) = a·da`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn point_load_deflection_change(
    length: f64,
    d_length: f64,
    compliance: &BeamCompliance,
    station: f64,
    d_station: f64,
    (force, d_force): (&Vec3, &Vec3),
    (moment, d_moment): (&Vec3, &Vec3),
) -> Vector6<f64> {
    let a = station.clamp(0.0, length);
    let (cy, cz) = (compliance.bending_y, compliance.bending_z);
    let d_by_force = a * a / 2.0 * d_length + (a * length - a * a / 2.0) * d_station;
    let d_by_moment = a * d_length + (length - a) * d_station;
    let d_turn = a * d_station;
    let held = point_load_deflection(length, compliance, station, d_force, d_moment);
    held + Vector6::new(
        force.x * d_station * compliance.axial,
        cz * (force.y * d_by_force + moment.z * d_by_moment),
        cy * (force.z * d_by_force - moment.y * d_by_moment),
        moment.x * d_station * compliance.torsion,
        cy * (-force.z * d_turn + moment.y * d_station),
        cz * (force.y * d_turn + moment.z * d_station),
    )
}

/// Tip deflection of a cantilever of length `length` under a uniform load `per_length`
/// (beam frame, N/m) along its whole length:
/// ```text
/// Δx = qx L²/2EA     Δy = qy L⁴/8EI_z     Δz = qz L⁴/8EI_y
/// Δα = 0             Δβ = −qz L³/6EI_y    Δγ = qy L³/6EI_z
/// ```
pub fn uniform_load_deflection(
    length: f64,
    compliance: &BeamCompliance,
    per_length: &Vec3,
) -> Vector6<f64> {
    let l2 = length * length;
    let (cy, cz) = (compliance.bending_y, compliance.bending_z);
    Vector6::new(
        per_length.x * l2 / 2.0 * compliance.axial,
        cz * per_length.y * l2 * l2 / 8.0,
        cy * per_length.z * l2 * l2 / 8.0,
        0.0,
        -cy * per_length.z * l2 * length / 6.0,
        cz * per_length.y * l2 * length / 6.0,
    )
}
