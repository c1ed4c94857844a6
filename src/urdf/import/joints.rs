//! One URDF joint converted, and the mimic joints resolved to the independent joints they
//! follow.

// The parent's types and imports.
use super::dofs::source_index;
use super::*;

impl Importer<'_> {
    pub(super) fn joint(
        &self,
        joint: &urdf_rs::Joint,
        parent: LinkId,
        child: LinkId,
        is_root_joint: bool,
        warnings: &mut Vec<String>,
    ) -> Result<Joint> {
        let kind = self.joint_kind(joint, is_root_joint, warnings)?;
        let xyz = joint.origin.xyz.0;
        let rpy = joint.origin.rpy.0;
        if xyz.iter().chain(rpy.iter()).any(|v| !v.is_finite()) {
            return Err(self.invalid(
                "joint",
                &joint.name,
                format!(
                    "joint '{}' has a non-finite <origin> (xyz=\"{} {} {}\" rpy=\"{} {} {}\")",
                    joint.name, xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2]
                ),
            ));
        }
        let parent_from_joint = pose(
            Vec3::new(xyz[0], xyz[1], xyz[2]),
            rotation_from_rpy(rpy[0], rpy[1], rpy[2]),
        );
        let raw_axis = Vec3::from(joint.axis.xyz.0);
        let axis = if kind.is_movable() {
            let norm = raw_axis.norm();
            if !norm.is_finite() || norm < 1e-9 {
                return Err(self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' has axis \"{} {} {}\", which has no direction; give a non-zero finite axis",
                        joint.name, raw_axis.x, raw_axis.y, raw_axis.z
                    ),
                ));
            }
            Unit::new_normalize(raw_axis)
        } else {
            Vec3::x_axis()
        };
        let limits = self.joint_limits(joint, kind, warnings)?;
        Ok(Joint {
            name: joint.name.clone(),
            kind,
            parent,
            child,
            parent_from_joint,
            axis,
            limits,
            actuation: Actuation::None,
        })
    }

    /// The kind of `joint`: a floating or planar joint at the root is fixed (with a warning),
    /// elsewhere an error.
    fn joint_kind(
        &self,
        joint: &urdf_rs::Joint,
        is_root_joint: bool,
        warnings: &mut Vec<String>,
    ) -> Result<JointKind> {
        use urdf_rs::JointType;
        Ok(match joint.joint_type {
            JointType::Fixed => JointKind::Fixed,
            JointType::Revolute => JointKind::Revolute,
            JointType::Continuous => JointKind::Continuous,
            JointType::Prismatic => JointKind::Prismatic,
            JointType::Floating | JointType::Planar if is_root_joint => {
                let kind = format!("{:?}", joint.joint_type).to_lowercase();
                warnings.push(format!(
                    "joint '{}' is {kind} at the root; treating it as fixed (the base does not move during calibration)",
                    joint.name
                ));
                JointKind::Fixed
            }
            ref other => {
                return Err(self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' has type {}, which treecal does not support; only revolute, continuous, prismatic and fixed joints (and a floating or planar joint at the root, treated as fixed) are accepted",
                        joint.name,
                        format!("{other:?}").to_lowercase()
                    ),
                ))
            }
        })
    }

    /// The limits of a revolute or prismatic joint (`None`: unbounded, or missing with a
    /// warning).
    fn joint_limits(
        &self,
        joint: &urdf_rs::Joint,
        kind: JointKind,
        warnings: &mut Vec<String>,
    ) -> Result<Option<Limits>> {
        Ok(match kind {
            JointKind::Revolute | JointKind::Prismatic => {
                let limit = &joint.limit;
                let (lower, upper) = (limit.lower, limit.upper);
                if lower.is_nan() || upper.is_nan() {
                    return Err(self.invalid(
                        "joint",
                        &joint.name,
                        format!(
                            "joint '{}' has a NaN limit (lower={lower} upper={upper})",
                            joint.name
                        ),
                    ));
                }
                if lower > upper {
                    return Err(self.invalid(
                        "joint",
                        &joint.name,
                        format!(
                            "joint '{}' has limits lower={lower} upper={upper}; lower must not exceed upper",
                            joint.name
                        ),
                    ));
                }
                // urdf-rs fills a missing <limit> with zeros; a joint that cannot move at all is
                // far more likely a missing element than a real limit.
                let all_zero = [lower, upper, limit.effort, limit.velocity]
                    .iter()
                    .all(|v| *v == 0.0);
                if all_zero {
                    warnings.push(format!(
                        "joint '{}' is {} but has no <limit> (or an all-zero one); treating it as unbounded",
                        joint.name,
                        kind.urdf_name()
                    ));
                    None
                } else {
                    (lower.is_finite() || upper.is_finite()).then_some(Limits { lower, upper })
                }
            }
            _ => None,
        })
    }

    pub(super) fn resolve_mimics(
        &self,
        robot: &urdf_rs::Robot,
        joints: &mut [Joint],
        position: &HashMap<&str, JointId>,
    ) -> Result<()> {
        for index in 0..joints.len() {
            if !joints[index].kind.is_movable() {
                continue;
            }
            let name = joints[index].name.clone();
            let Some(first) = robot.joints[source_index(robot, &name)].mimic.as_ref() else {
                continue;
            };
            if matches!(joints[index].actuation, Actuation::Independent(_)) {
                // A mimic of a joint that does not exist, made independent above.
                continue;
            }
            // Follow mimic → mimic chains to an independent joint, composing the affine maps.
            let (mut multiplier, mut offset) = (1.0, 0.0);
            let mut mimic = first;
            let mut visited = vec![name.clone()];
            loop {
                (multiplier, offset) =
                    self.compose(&name, &visited, mimic, (multiplier, offset))?;
                let master = *position.get(mimic.joint.as_str()).ok_or_else(|| {
                    self.invalid(
                        "joint",
                        &name,
                        format!(
                            "joint '{name}' mimics joint '{}', which does not exist{}",
                            mimic.joint,
                            crate::error::did_you_mean(&mimic.joint, position.keys().copied())
                        ),
                    )
                })?;
                if visited.contains(&mimic.joint) {
                    return Err(self.invalid(
                        "joint",
                        &name,
                        format!(
                            "mimic joints {} → {} follow each other in a cycle; one of them must be independent",
                            visited.join(" → "),
                            mimic.joint
                        ),
                    ));
                }
                visited.push(mimic.joint.clone());
                match joints[master.0].actuation {
                    Actuation::Independent(dof) => {
                        joints[index].actuation = Actuation::Mimic {
                            master: dof,
                            multiplier,
                            offset,
                        };
                        break;
                    }
                    _ if !joints[master.0].kind.is_movable() => {
                        return Err(self.invalid(
                            "joint",
                            &name,
                            format!(
                                "joint '{name}' mimics joint '{}', which is fixed",
                                mimic.joint
                            ),
                        ));
                    }
                    // The master is itself a mimic (movable, not independent): follow it.
                    _ => match robot.joints[source_index(robot, &mimic.joint)]
                        .mimic
                        .as_ref()
                    {
                        Some(next) => mimic = next,
                        None => break,
                    },
                }
            }
        }
        Ok(())
    }

    /// The affine map `(multiplier, offset)` of a mimic chain followed one more link,
    /// `mimic`: value = multiplier·(m·q_master + o) + offset; an error when a factor is not
    /// finite or the product grows out of bounds.
    fn compose(
        &self,
        name: &str,
        visited: &[String],
        mimic: &urdf_rs::Mimic,
        (mut multiplier, mut offset): (f64, f64),
    ) -> Result<(f64, f64)> {
        let m = mimic.multiplier.unwrap_or(1.0);
        let o = mimic.offset.unwrap_or(0.0);
        if !m.is_finite() || !o.is_finite() {
            return Err(self.invalid(
                "joint",
                name,
                format!("joint '{name}' has a non-finite <mimic> multiplier or offset"),
            ));
        }
        // value = multiplier·(m·q_master + o) + offset
        offset += multiplier * o;
        multiplier *= m;
        // Each factor is bounded, their product is not: a long chain can overflow.
        let composed = magnitude_problem(multiplier, Quantity::Factor)
            .map(|p| format!("multiplier: {p}"))
            .or_else(|| {
                magnitude_problem(offset, Quantity::JointLimit).map(|p| format!("offset: {p}"))
            });
        if let Some(problem) = composed {
            return Err(self.invalid(
                "joint",
                name,
                format!(
                    "the <mimic> chain {} → {} composes to a {problem}; shorten the chain \
                     or reduce its multipliers",
                    visited.join(" → "),
                    mimic.joint
                ),
            ));
        }
        Ok((multiplier, offset))
    }
}
