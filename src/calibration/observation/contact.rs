//! Contacts (issue 29): the robot's own geometry measured by touching a plane, itself, or the
//! two ends of a bar. A contact has no instrument reading: its measured value is zero and its
//! prediction is how far the contact is from holding at the current parameters. Rows:
//!
//! - `flush` (3): a face on the tool lies in a plane: its height above the plane (m) and its
//!   two tilts against it (rad, the face normal's components along the plane's in-plane axes);
//! - `point` (1): the tool's contact point lies in a plane: its height (m);
//! - `touch` (3): two tools' contact points coincide: the gap `x₁ − x₂` (m);
//! - `distance` (1): two tools' contact points lie a bar's length apart: `‖x₁ − x₂‖ − L` (m).
//!
//! Planes, contact points, faces and bar lengths are [`Nuisance`](super::Nuisance) blocks
//! ([`crate::measurement::Contact`] names them); the Jacobian has analytic columns for the
//! robot (the tools' motion `∂predicted/∂ξ` chained with the tool Jacobians) and for them.
//! A linear flexibility offset (`RobotState::offset`) is not applied to contacts. The math is
//! in `docs/contacts.md`.

use super::{MeasurementKind, RobotState, RowKind};
use crate::error::{Error, Result};
use crate::math::{Pose, Vec3};
use crate::measurement::{Contact, ContactPlane, Observation};
use nalgebra::{DMatrix, DMatrixViewMut, Matrix3, SMatrix};

const FLUSH: [RowKind; 3] = [RowKind::Height, RowKind::Tilt, RowKind::Tilt];
const POINT: [RowKind; 1] = [RowKind::Height];
const TOUCH: [RowKind; 3] = [RowKind::Gap; 3];
const DISTANCE: [RowKind; 1] = [RowKind::Length];

/// Up to three rows of one column.
type Column = [f64; 3];

/// A contact's prediction at one robot state, with its derivatives.
struct Evaluation {
    /// The predicted value of each row (the contact's violation; zero when it holds).
    predicted: Column,
    /// `∂predicted/∂ξ` (3 × 6, rows past the contact's count zero) per tool it involves.
    motions: Vec<(usize, SMatrix<f64, 3, 6>)>,
    /// `∂predicted/∂ν` per nuisance value it involves (index among the nuisance values).
    nuisance: Vec<(usize, Column)>,
}

/// `Rx(a)·Ry(b)` and its derivatives with respect to `a` and `b`.
pub(crate) fn tilted(a: f64, b: f64) -> [Matrix3<f64>; 3] {
    let (sa, ca) = a.sin_cos();
    let (sb, cb) = b.sin_cos();
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, ca, -sa, 0.0, sa, ca);
    let drx = Matrix3::new(0.0, 0.0, 0.0, 0.0, -sa, -ca, 0.0, ca, -sa);
    let ry = Matrix3::new(cb, 0.0, sb, 0.0, 1.0, 0.0, -sb, 0.0, cb);
    let dry = Matrix3::new(-sb, 0.0, cb, 0.0, 0.0, 0.0, -cb, 0.0, -sb);
    [rx * ry, drx * ry, rx * dry]
}

/// `[v]×`: `skew(v)·w = v × w`.
fn skew(v: &Vec3) -> Matrix3<f64> {
    v.cross_matrix()
}

/// A plane at the current nuisance values: its nominal origin `o`, height `h`, axes (columns
/// `e₁`, `e₂`, `n`) and the axes' derivatives with respect to its two tilts.
struct PlaneAt {
    origin: Vec3,
    height: f64,
    axes: Matrix3<f64>,
    d_axes: [Matrix3<f64>; 2],
}

fn plane_at(plane: &ContactPlane, at: &RobotState<'_>) -> Result<PlaneAt> {
    let v = values::<3>(at, plane.block, "plane")?;
    let r0 = plane.nominal.rotation.to_rotation_matrix().into_inner();
    let [l, la, lb] = tilted(v[1], v[2]);
    Ok(PlaneAt {
        origin: plane.nominal.translation.vector,
        height: v[0],
        axes: r0 * l,
        d_axes: [r0 * la, r0 * lb],
    })
}

/// Block `block`'s `N` values, or an error naming what the contact expected.
fn values<const N: usize>(at: &RobotState<'_>, block: usize, what: &str) -> Result<[f64; N]> {
    let values = at.nuisance.block_values(block)?;
    values.try_into().map_err(|_| Error::InvalidData {
        origin: "contact".into(),
        message: format!(
            "nuisance block {block} ({what}) has {} values, not {N}",
            values.len()
        ),
    })
}

/// The motion of a point `r` (from the tool's origin, measurement frame) under `ξ`:
/// `δx = δp − [r]×·δω`, as a 3 × 6 matrix.
fn point_motion(r: &Vec3) -> SMatrix<f64, 3, 6> {
    let mut m = SMatrix::<f64, 3, 6>::zeros();
    m.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(r)));
    m
}

impl Contact {
    fn evaluate(&self, at: &RobotState<'_>) -> Result<Evaluation> {
        let offset = |block: usize| at.nuisance.offset(block);
        match *self {
            Contact::Point { plane, point } => {
                let tool = at.tool_pose(at.tool)?;
                let c = Vec3::from(values::<3>(at, point, "contact point")?);
                let rotation = tool.rotation.to_rotation_matrix().into_inner();
                let r = rotation * c;
                let x = tool.translation.vector + r;
                let p = plane_at(&plane, at)?;
                let n = p.axes.column(2).into_owned();
                let from = x - p.origin;
                let mut motion = SMatrix::<f64, 3, 6>::zeros();
                motion
                    .fixed_view_mut::<1, 3>(0, 0)
                    .copy_from(&n.transpose());
                motion
                    .fixed_view_mut::<1, 3>(0, 3)
                    .copy_from(&r.cross(&n).transpose());
                let along = rotation.transpose() * n;
                let mut nuisance = vec![
                    (offset(plane.block), [-1.0, 0.0, 0.0]),
                    (
                        offset(plane.block) + 1,
                        [p.d_axes[0].column(2).dot(&from), 0.0, 0.0],
                    ),
                    (
                        offset(plane.block) + 2,
                        [p.d_axes[1].column(2).dot(&from), 0.0, 0.0],
                    ),
                ];
                nuisance.extend((0..3).map(|k| (offset(point) + k, [along[k], 0.0, 0.0])));
                Ok(Evaluation {
                    predicted: [n.dot(&from) - p.height, 0.0, 0.0],
                    motions: vec![(at.tool, motion)],
                    nuisance,
                })
            }
            Contact::Flush { .. } => self.evaluate_flush(at),
            Contact::Touch { .. } | Contact::Distance { .. } => self.evaluate_pair(at),
        }
    }

    /// A face flush with a plane: height of the face point, tilts `a·e₁`, `a·e₂` of the face
    /// normal `a` (measurement frame).
    fn evaluate_flush(&self, at: &RobotState<'_>) -> Result<Evaluation> {
        let Contact::Flush { plane, face } = *self else {
            return Err(not_a("flush"));
        };
        let tool = at.tool_pose(at.tool)?;
        let rotation = tool.rotation.to_rotation_matrix().into_inner();
        let [d, ua, ub] = values::<3>(at, face.block, "contact face")?;
        let rf = face.nominal.rotation.to_rotation_matrix().into_inner();
        let [l, la, lb] = tilted(ua, ub);
        let m = (rf * l).column(2).into_owned();
        let f = face.nominal.translation.vector + m * d;
        let r = rotation * f;
        let x = tool.translation.vector + r;
        let a = rotation * m;
        let p = plane_at(&plane, at)?;
        let (e1, e2, n) = (
            p.axes.column(0).into_owned(),
            p.axes.column(1).into_owned(),
            p.axes.column(2).into_owned(),
        );
        let from = x - p.origin;
        let mut motion = SMatrix::<f64, 3, 6>::zeros();
        motion
            .fixed_view_mut::<1, 3>(0, 0)
            .copy_from(&n.transpose());
        motion
            .fixed_view_mut::<1, 3>(0, 3)
            .copy_from(&r.cross(&n).transpose());
        motion
            .fixed_view_mut::<1, 3>(1, 3)
            .copy_from(&a.cross(&e1).transpose());
        motion
            .fixed_view_mut::<1, 3>(2, 3)
            .copy_from(&a.cross(&e2).transpose());
        let (plane_at0, face_at0) = (
            at.nuisance.offset(plane.block),
            at.nuisance.offset(face.block),
        );
        let mut nuisance = vec![(plane_at0, [-1.0, 0.0, 0.0])];
        for (k, d_axes) in p.d_axes.iter().enumerate() {
            nuisance.push((
                plane_at0 + 1 + k,
                [
                    d_axes.column(2).dot(&from),
                    a.dot(&d_axes.column(0)),
                    a.dot(&d_axes.column(1)),
                ],
            ));
        }
        nuisance.push((face_at0, [n.dot(&a), 0.0, 0.0]));
        for (k, dl) in [la, lb].iter().enumerate() {
            let da = rotation * (rf * dl).column(2);
            nuisance.push((face_at0 + 1 + k, [n.dot(&da) * d, da.dot(&e1), da.dot(&e2)]));
        }
        Ok(Evaluation {
            predicted: [n.dot(&from) - p.height, a.dot(&e1), a.dot(&e2)],
            motions: vec![(at.tool, motion)],
            nuisance,
        })
    }

    /// Two contact points: their gap `x₁ − x₂` (touch) or distance `‖x₁ − x₂‖ − L`.
    fn evaluate_pair(&self, at: &RobotState<'_>) -> Result<Evaluation> {
        let (point, tool2, point2, length) = match *self {
            Contact::Touch {
                point,
                tool2,
                point2,
            } => (point, tool2, point2, None),
            Contact::Distance {
                point,
                tool2,
                point2,
                length,
            } => (point, tool2, point2, Some(length)),
            _ => return Err(not_a("touch or distance")),
        };
        let ends = [(at.tool, point), (tool2, point2)].map(|(tool, block)| {
            let pose = at.tool_pose(tool)?;
            let rotation = pose.rotation.to_rotation_matrix().into_inner();
            let r = rotation * Vec3::from(values::<3>(at, block, "contact point")?);
            Ok::<_, Error>((tool, block, rotation, r, pose.translation.vector + r))
        });
        let [first, second] = ends;
        let (first, second) = (first?, second?);
        let gap = first.4 - second.4;
        // Rows: the gap itself (touch) or its component along the unit direction (distance).
        let (rows, predicted) = match length {
            None => (Matrix3::identity(), [gap.x, gap.y, gap.z]),
            Some(block) => {
                let [bar] = values::<1>(at, block, "bar length")?;
                let distance = gap.norm();
                let u = if distance > 0.0 {
                    gap / distance
                } else {
                    Vec3::x()
                };
                let mut rows = Matrix3::zeros();
                rows.row_mut(0).copy_from(&u.transpose());
                (rows, [distance - bar, 0.0, 0.0])
            }
        };
        let mut nuisance = Vec::new();
        let mut motions = Vec::new();
        for (sign, (tool, block, rotation, r, _)) in [(1.0, first), (-1.0, second)] {
            motions.push((tool, rows * point_motion(&r) * sign));
            let columns = rows * rotation * sign;
            for k in 0..3 {
                let c = columns.column(k);
                nuisance.push((at.nuisance.offset(block) + k, [c[0], c[1], c[2]]));
            }
        }
        if let Some(block) = length {
            nuisance.push((at.nuisance.offset(block), [-1.0, 0.0, 0.0]));
        }
        Ok(Evaluation {
            predicted,
            motions,
            nuisance,
        })
    }
}

fn not_a(kind: &str) -> Error {
    Error::InvalidData {
        origin: "contact".into(),
        message: format!("not a {kind} contact"),
    }
}

impl MeasurementKind for Contact {
    fn name(&self) -> &'static str {
        Contact::name(self)
    }

    fn row_kinds(&self) -> &'static [RowKind] {
        match self {
            Contact::Flush { .. } => &FLUSH,
            Contact::Point { .. } => &POINT,
            Contact::Touch { .. } => &TOUCH,
            Contact::Distance { .. } => &DISTANCE,
        }
    }

    fn is_finite(&self) -> bool {
        let planes = match self {
            Contact::Flush { plane, face } => vec![plane.nominal, face.nominal],
            Contact::Point { plane, .. } => vec![plane.nominal],
            _ => Vec::new(),
        };
        planes.iter().all(|p| {
            p.translation
                .vector
                .iter()
                .chain(p.rotation.coords.iter())
                .all(|v| v.is_finite())
        })
    }

    fn residual(&self, at: &RobotState<'_>, out: &mut [f64]) -> Result<()> {
        let evaluation = self.evaluate(at)?;
        for (value, predicted) in out.iter_mut().zip(evaluation.predicted) {
            *value = -predicted;
        }
        Ok(())
    }

    fn jacobian(
        &self,
        at: &RobotState<'_>,
        columns: &[usize],
        out: &mut DMatrixViewMut<'_, f64>,
    ) -> Result<()> {
        let evaluation = self.evaluate(at)?;
        let rows = self.rows();
        let model_columns = at.model.parameter_count();
        let tools = evaluation
            .motions
            .iter()
            .map(|(tool, motion)| Ok((at.tool_jacobian(*tool)?, motion)))
            .collect::<Result<Vec<_>>>()?;
        for (column, &parameter) in columns.iter().enumerate() {
            let mut to = out.column_mut(column);
            to.fill(0.0);
            if parameter < model_columns {
                for (tool, motion) in &tools {
                    let from = tool.jacobian.column(parameter);
                    let moved = *motion * from.fixed_rows::<6>(0);
                    for k in 0..rows {
                        to[k] += moved[k];
                    }
                }
            } else if let Some((_, values)) = evaluation
                .nuisance
                .iter()
                .find(|(index, _)| *index == parameter - model_columns)
            {
                for k in 0..rows {
                    to[k] = values[k];
                }
            }
        }
        Ok(())
    }

    fn tool_motion_jacobian(&self, at: &RobotState<'_>, tool: usize) -> DMatrix<f64> {
        let rows = self.rows();
        let mut total = DMatrix::zeros(rows, 6);
        if let Ok(evaluation) = self.evaluate(at) {
            for (_, motion) in evaluation.motions.iter().filter(|(t, _)| *t == tool) {
                total += motion.rows(0, rows);
            }
        }
        total
    }

    fn measured_point(&self) -> Option<Vec3> {
        None
    }

    fn in_frame(&self, new_from_old: &Pose) -> Observation {
        let mut contact = *self;
        match &mut contact {
            Contact::Flush { plane, .. } | Contact::Point { plane, .. } => {
                plane.nominal = new_from_old * plane.nominal;
            }
            Contact::Touch { .. } | Contact::Distance { .. } => {}
        }
        Observation::Contact(Box::new(contact))
    }

    fn noise_free(&self, _at: &RobotState<'_>) -> Result<Observation> {
        // A contact has no reading: a perfect contact is the contact itself (simulation puts
        // the configurations where it holds).
        Ok(Observation::Contact(Box::new(*self)))
    }
}

/// The predicted violation of `contact` at `at` (zero when it holds): what simulation drives
/// to zero when it places configurations on the contact.
pub fn contact_violation(contact: &Contact, at: &RobotState<'_>) -> Result<Vec<f64>> {
    let evaluation = contact.evaluate(at)?;
    Ok(evaluation.predicted[..contact.rows()].to_vec())
}
