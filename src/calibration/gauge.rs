//! The gauge freedom of a model measured from a reference link, and the parameters that fix it.
//!
//! Measured from the URDF root, the root frame is where the measurement frame is fitted: the
//! MCPC parameters are complete and minimal. Measured from a reference link (a sole), every
//! observation is a pose *relative to that link*, and the root link is just a frame somewhere
//! on the body between the chains: moving it by any rigid transform `G`
//! (`root_from_x → G·root_from_x` for every link `x`) changes no relative pose. The MCPC
//! parameters are complete, so each such move is a change of the parameters (the first frames
//! of every chain off the root, the conventions they pass down to the tools, and the
//! measurement frame at the reference end): six directions in parameter space that no data
//! can see. Left free they make every fit rank-deficient by six, spread into "unidentifiable"
//! combinations of nearly every root-side parameter.
//!
//! [`reference_gauge`] fixes the gauge the way the root reference does: six parameters of the
//! frames at the root keep their start (URDF) values — first the reference path's own first
//! frame (its four parameters place the root on that joint's axis), then the remaining
//! directions by pivoting on the other root-side parameters. The gauge directions are found
//! numerically as the structural null space of the model's Jacobian at a dozen fixed,
//! generic configurations (data independent: a deficiency of the data is still reported as
//! such). See `docs/mcpc.md`, "Reference link".

use crate::kinematics::{McpcModel, ParameterOwner};
use crate::tree::KinematicTree;
use nalgebra::DMatrix;

/// Configurations the structural null space is computed at.
const CONFIGURATIONS: usize = 12;

/// Singular values below this times the largest (columns scaled to unit norm) are null.
const NULL_TOLERANCE: f64 = 1e-8;

/// A candidate's remaining weight in the null space must exceed this to fix a direction.
const PIVOT_TOLERANCE: f64 = 1e-3;

/// The parameters (among `free`, flat indices of `model`) to keep at their start values so that
/// the gauge freedom of the root's placement, which a reference link other than the root
/// leaves, is fixed. Empty without a reference link or when `free` has no gauge freedom.
pub fn reference_gauge(model: &McpcModel, free: &[usize]) -> Vec<usize> {
    if model.reference().is_none() || free.is_empty() {
        return Vec::new();
    }
    let null = structural_null_space(model, free);
    if null.ncols() == 0 {
        return Vec::new();
    }
    let layout = model.parameter_layout();
    let first = model.reference_chain().first().copied();
    let root_side = |p: usize| match layout[p].0 {
        ParameterOwner::Frame(f) => model.frames()[f].parent.is_none(),
        ParameterOwner::Tool(t) => model.tools()[t].parent.is_none(),
        ParameterOwner::Measurement => false,
    };
    // Tiers: the reference path's first frame, then the other root-side frames and tools.
    let tier = |p: usize| match layout[p].0 {
        ParameterOwner::Frame(f) if Some(f) == first => 0,
        _ if root_side(p) => 1,
        _ => 2,
    };
    let mut basis: Vec<nalgebra::DVector<f64>> = Vec::new();
    let mut kept = Vec::new();
    for level in 0..3 {
        loop {
            if basis.len() == null.ncols() {
                return kept;
            }
            let best = (0..free.len())
                .filter(|&i| tier(free[i]) == level && !kept.contains(&free[i]))
                .map(|i| {
                    let mut row = null.row(i).transpose();
                    for b in &basis {
                        row -= b * b.dot(&row);
                    }
                    (i, row)
                })
                .max_by(|a, b| a.1.norm().total_cmp(&b.1.norm()));
            match best {
                Some((i, row)) if row.norm() > PIVOT_TOLERANCE => {
                    basis.push(row.normalize());
                    kept.push(free[i]);
                }
                _ => break,
            }
        }
    }
    kept
}

/// An orthonormal basis (columns, one row per entry of `free`) of the directions of the free
/// parameters that change no tool pose at any configuration: the null space of the stacked
/// Jacobians at [`CONFIGURATIONS`] fixed configurations, columns scaled to unit norm.
fn structural_null_space(model: &McpcModel, free: &[usize]) -> DMatrix<f64> {
    let dofs = model
        .frames()
        .iter()
        .filter_map(|f| f.actuation.driver().map(|d| d.0))
        .max()
        .map_or(0, |d| d + 1);
    let tools = model.tools().len();
    let mut stacked = DMatrix::zeros(6 * tools * CONFIGURATIONS, free.len());
    for k in 0..CONFIGURATIONS {
        // Fixed, generic joint values within ±0.9 rad (or m/10 for a slider).
        let q: Vec<f64> = (0..dofs)
            .map(|d| 0.9 * ((1.7 * d as f64 + 2.3 * k as f64 + 0.4).sin()))
            .collect();
        for (t, jacobian) in model.tool_jacobians(&q).iter().enumerate() {
            let row = 6 * (tools * k + t);
            for (c, &p) in free.iter().enumerate() {
                for r in 0..6 {
                    stacked[(row + r, c)] = jacobian.jacobian[(r, p)];
                }
            }
        }
    }
    if !stacked.iter().all(|v| v.is_finite()) {
        return DMatrix::zeros(free.len(), 0);
    }
    for mut column in stacked.column_iter_mut() {
        let norm = column.norm();
        if norm > 0.0 {
            column /= norm;
        }
    }
    let svd = stacked.svd(false, true);
    let Some(v_t) = svd.v_t else {
        return DMatrix::zeros(free.len(), 0);
    };
    let largest = svd.singular_values.max();
    let null: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&i| svd.singular_values[i] <= NULL_TOLERANCE * largest)
        .collect();
    // Rows of v_t beyond the singular values (more columns than rows) are null too; with
    // 6·tools·12 rows that does not happen for any robot treecal calibrates.
    let mut basis = DMatrix::zeros(free.len(), null.len());
    for (c, &i) in null.iter().enumerate() {
        basis.set_column(c, &v_t.row(i).transpose());
    }
    basis
}

/// What a reference link hides, in words, for `check`, `plan`, `simulate` and the verdict
/// notes (`None` without a reference chain): the measurement frame absorbs the reference link's
/// own placement, and the root link's placement between the chains is a gauge freedom fixed by
/// the named parameters keeping their URDF values.
pub fn gauge_summary(model: &McpcModel, tree: &KinematicTree) -> Option<String> {
    let reference = model.reference()?;
    if model.reference_chain().is_empty() {
        return None;
    }
    let all: Vec<usize> = (0..model.parameter_count()).collect();
    let kept = reference_gauge(model, &all);
    let names: Vec<String> = kept
        .iter()
        .map(|&p| model.parameter_name(tree, p))
        .collect();
    let link = &tree.link(reference.link).name;
    let root = &tree.link(tree.root()).name;
    let mut text = format!(
        "measured from '{link}', the measurement frame's six parameters are fitted with the geometry (they absorb where '{link}' sits after its last joint, which no measurement relative to it can see)"
    );
    if !names.is_empty() {
        text += &format!(
            "; where the root link '{root}' sits between the chains is invisible too ({} directions of the parameters change no pose relative to '{link}'), so {} keep their URDF values",
            names.len(),
            names.join(", ")
        );
    }
    Some(text)
}
