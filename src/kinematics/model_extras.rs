//! What an MCPC model carries beyond its frames and tools: the joint-angle error values
//! (`joint_errors`), the measurement frame as parameters, and the chain to a reference link
//! (`reference`). Data only, below the model, so that the model holds them and the files that
//! implement them import the model, not the other way round.

use crate::error::Result;
use crate::math::{rot_x, rot_y, rot_z, Pose, Transform, Vec3};
use crate::tree::{JointId, KinematicTree, LinkId};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// The joint-error values of a model: per frame, one optional value per kind of
/// [`JOINT_ERROR_KINDS`](super::joint_errors::JOINT_ERROR_KINDS) (`None`: not a parameter, zero).
#[derive(Debug, Clone, Default)]
pub(crate) struct JointErrors {
    pub(crate) slots: Vec<[Option<f64>; 4]>,
    pub(crate) gravity: Option<Arc<GravitySigns>>,
}

impl PartialEq for JointErrors {
    fn eq(&self, other: &Self) -> bool {
        self.slots == other.slots && self.gravity.is_some() == other.gravity.is_some()
    }
}

impl JointErrors {
    /// Whether any joint has an error term.
    #[inline]
    pub(crate) fn is_active(&self) -> bool {
        !self.slots.is_empty()
    }
}

/// The measurement frame as six parameters: `world_from_base = (R(α, β, γ)·R₀, p₀ + t)` with
/// `R = Rx(α)·Ry(β)·Rz(γ)` turning about the base origin and `(p₀, R₀)` the reference frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FrameParameters {
    /// α, β, γ (rad), x, y, z (m).
    pub(crate) values: [f64; 6],
    /// The frame the parameters are relative to.
    pub(crate) reference: Transform,
}

impl FrameParameters {
    pub(crate) fn effective(&self) -> Transform {
        let [a, b, c, x, y, z] = self.values;
        Transform {
            rotation: (rot_x(a) * rot_y(b) * rot_z(c))
                .to_rotation_matrix()
                .into_inner()
                * self.reference.rotation,
            translation: self.reference.translation + Vec3::new(x, y, z),
        }
    }
}

/// The sign of the gravity torque about every MCPC joint axis at a configuration, from the
/// URDF's link inertials at the nominal tree (gravity along −z of the root link). Cached per
/// configuration.
#[derive(Debug)]
pub struct GravitySigns {
    pub(super) tree: KinematicTree,
    /// Per MCPC frame: its joint and the links with a mass that it carries.
    pub(super) carried: Vec<(JointId, Vec<LinkId>)>,
    pub(super) cache: Mutex<HashMap<Vec<u64>, Arc<Vec<f64>>>>,
}

/// Standard gravity (m/s²).
const GRAVITY: f64 = 9.806_65;

/// At most this many configurations are cached; beyond it the cache starts over.
const CACHE_LIMIT: usize = 100_000;

impl GravitySigns {
    /// The gravity torque about every MCPC joint axis at `q` (N·m, one per frame).
    pub fn torques(&self, q: &[f64]) -> Result<Vec<f64>> {
        let poses = self.tree.link_poses(q)?;
        let gravity = Vec3::new(0.0, 0.0, -GRAVITY);
        Ok(self
            .carried
            .iter()
            .map(|(joint, links)| {
                let joint = self.tree.joint(*joint);
                let child = &poses[joint.child.0];
                let axis = child.rotation * joint.axis.into_inner();
                let origin = child.translation.vector;
                links
                    .iter()
                    .filter_map(|l| {
                        let inertial = self.tree.link(*l).inertial.as_ref()?;
                        let com = poses[l.0] * nalgebra::Point3::from(inertial.center_of_mass());
                        Some(axis.dot(&(com.coords - origin).cross(&(gravity * inertial.mass))))
                    })
                    .sum()
            })
            .collect())
    }

    /// The torque signs at `q` (±1, 0 for a torque below 1e-9 N·m or a configuration of the
    /// wrong size).
    pub fn signs(&self, q: &[f64]) -> Arc<Vec<f64>> {
        let key: Vec<u64> = q.iter().map(|v| (v + 0.0).to_bits()).collect();
        let mut cache = self
            .cache
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some(found) = cache.get(&key) {
            return found.clone();
        }
        let signs = Arc::new(match self.torques(q) {
            Ok(torques) => torques
                .iter()
                .map(|t| if t.abs() < 1e-9 { 0.0 } else { t.signum() })
                .collect(),
            Err(_) => vec![0.0; self.carried.len()],
        });
        if cache.len() >= CACHE_LIMIT {
            cache.clear();
        }
        cache.insert(key, signs.clone());
        signs
    }
}
/// The reference link of a model: where it hangs in the MCPC chain.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceLink {
    /// The link fixed in the world.
    pub link: LinkId,
    /// The last MCPC frame on the path from the root to the link (`None`: rigid on the root).
    pub parent: Option<usize>,
    /// The link's frame in that frame after its joint's motion (constant, not a parameter).
    pub last_from_link: Pose,
}

/// [`ReferenceLink`] with what forward kinematics needs cached.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ReferenceChain {
    pub(crate) reference: ReferenceLink,
    /// The frames from the root to the reference link, root side first.
    pub(crate) chain: Vec<usize>,
    /// `last_from_link` in the fast form.
    pub(crate) last_from_link: Transform,
}

/// The inverse of a rigid transform: (Rᵀ, −Rᵀ·t).
pub(crate) fn inverse(transform: &Transform) -> Transform {
    let rotation = transform.rotation.transpose();
    Transform {
        translation: -(rotation * transform.translation),
        rotation,
    }
}
