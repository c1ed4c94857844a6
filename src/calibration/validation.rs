//! Where each validation configuration lies relative to the identification data: a repeat of
//! an identification posture, a new posture inside the identification joint ranges, or one
//! outside them (`docs/calibration.md`, "Errors before and after"). Every validation row is
//! counted in the figures; the strata tell how far the result carries.

use crate::kinematics::{FrameKind, McpcModel};
use crate::measurement::Measurement;
use serde::Serialize;

/// A validation row repeats an identification posture when every joint of its tool's chain
/// is within this of that posture's value (rad; a plateau average of a repeated posture
/// differs by well under a milliradian).
pub const REPEAT_ANGLE: f64 = 0.01;

/// The same for prismatic joints (m).
pub const REPEAT_LENGTH: f64 = 0.001;

/// A joint value beyond the identification range by less than this still counts as inside
/// (rad): a few degrees do not change what the data determine.
pub const INSIDE_MARGIN_ANGLE: f64 = 0.05;

/// The same for prismatic joints (m).
pub const INSIDE_MARGIN_LENGTH: f64 = 0.005;

/// Where a validation configuration lies relative to the identification configurations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stratum {
    /// It repeats an identification posture (within [`REPEAT_ANGLE`], [`REPEAT_LENGTH`]).
    Repeat,
    /// A new posture, every joint of the tool's chain inside the identification range.
    Inside,
    /// A new posture with a joint outside the identification range (extrapolation).
    Outside,
}

impl Stratum {
    /// `repeat`, `inside` or `outside`.
    pub fn as_str(self) -> &'static str {
        match self {
            Stratum::Repeat => "repeat",
            Stratum::Inside => "inside",
            Stratum::Outside => "outside",
        }
    }

    /// In words, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Stratum::Repeat => "repeat an identification posture",
            Stratum::Inside => "new postures inside the identification joint ranges",
            Stratum::Outside => "postures outside the identification joint ranges",
        }
    }
}

/// The independent joint values a tool's chain depends on, with whether each is an angle.
fn chain_dofs(model: &McpcModel, tool: usize) -> Vec<(usize, bool)> {
    let Some(chain) = (tool < model.tools().len()).then(|| model.tool_chain(tool)) else {
        return Vec::new();
    };
    let mut dofs: Vec<(usize, bool)> = Vec::new();
    for &f in chain {
        let frame = &model.frames()[f];
        let Some(dof) = frame.actuation.driver().map(|d| d.0) else {
            continue;
        };
        if !dofs.iter().any(|(d, _)| *d == dof) {
            dofs.push((dof, frame.kind == FrameKind::Revolute));
        }
    }
    dofs
}

/// The identification postures of one tool, on the independent joints of its chain: what a
/// validation row of that tool is judged against.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainPostures {
    /// The configuration index of each joint of the chain, with whether it is an angle.
    pub dofs: Vec<(usize, bool)>,
    /// Per identification row of the tool, its value of each joint of `dofs` (rad, m).
    pub postures: Vec<Vec<f64>>,
}

impl ChainPostures {
    /// The smallest and largest identification value of each joint of the chain (the
    /// calibrated ranges; infinite without postures).
    pub fn ranges(&self) -> Vec<(f64, f64)> {
        (0..self.dofs.len())
            .map(|k| {
                self.postures
                    .iter()
                    .map(|p| p[k])
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                        (l.min(v), h.max(v))
                    })
            })
            .collect()
    }

    /// Where a configuration `q` of this tool lies: a repeat of a posture, inside the ranges
    /// (within the margins) or outside them. For many configurations, [`Self::index`] once.
    pub fn stratum(&self, q: &[f64]) -> Stratum {
        self.index().stratum(q)
    }

    /// The postures prepared for many [`PostureIndex::stratum`] look-ups.
    pub fn index(&self) -> PostureIndex<'_> {
        let ranges = self.ranges();
        // The joint that spreads the postures over the most tolerances: sorted along it, a
        // repeat is searched among the few postures near `q` on that joint.
        let key = (0..self.dofs.len())
            .max_by(|&a, &b| {
                let spread =
                    |k: usize| (ranges[k].1 - ranges[k].0) / repeat_tolerance(self.dofs[k].1);
                spread(a).total_cmp(&spread(b))
            })
            .unwrap_or(0);
        let mut order: Vec<usize> = (0..self.postures.len()).collect();
        if !self.dofs.is_empty() {
            order.sort_by(|&a, &b| self.postures[a][key].total_cmp(&self.postures[b][key]));
        }
        let keys = order
            .iter()
            .map(|&i| self.postures[i].get(key).copied().unwrap_or(0.0))
            .collect();
        PostureIndex {
            chain: self,
            ranges,
            key,
            order,
            keys,
        }
    }
}

fn repeat_tolerance(angle: bool) -> f64 {
    if angle {
        REPEAT_ANGLE
    } else {
        REPEAT_LENGTH
    }
}

/// [`ChainPostures`] prepared for many look-ups ([`ChainPostures::index`]): the ranges computed
/// once, the postures sorted along one joint. Each look-up is logarithmic in the number of
/// postures (plus the postures near `q` on that joint), with the same result as a scan of all.
#[derive(Debug, Clone)]
pub struct PostureIndex<'a> {
    chain: &'a ChainPostures,
    ranges: Vec<(f64, f64)>,
    /// The position in `chain.dofs` of the joint the postures are sorted along.
    key: usize,
    /// Posture indices, sorted by their value of the key joint.
    order: Vec<usize>,
    /// Those values, in the same order.
    keys: Vec<f64>,
}

impl PostureIndex<'_> {
    /// The identification posture (its index in [`ChainPostures::postures`], the first of
    /// several) that a configuration `q` of this tool repeats, if any.
    pub fn repeat_of(&self, q: &[f64]) -> Option<usize> {
        let chain = self.chain;
        let value = |dof: usize| q.get(dof).copied().unwrap_or(0.0);
        let repeats_posture = |posture: &Vec<f64>| {
            chain
                .dofs
                .iter()
                .zip(posture)
                .all(|(&(d, angle), &p)| (p - value(d)).abs() <= repeat_tolerance(angle))
        };
        if chain.dofs.is_empty() {
            return (!chain.postures.is_empty()).then_some(0);
        }
        // A window twice the tolerance wide on the key joint holds every candidate; the full
        // test decides, exactly as a scan of every posture would.
        let (dof, angle) = chain.dofs[self.key];
        let v = value(dof);
        let reach = 2.0 * repeat_tolerance(angle);
        let start = self.keys.partition_point(|&k| k < v - reach);
        self.keys[start..]
            .iter()
            .zip(&self.order[start..])
            .take_while(|(&k, _)| k <= v + reach)
            .map(|(_, &i)| i)
            .filter(|&i| repeats_posture(&chain.postures[i]))
            .min()
    }

    /// Where a configuration `q` of this tool lies ([`ChainPostures::stratum`]).
    pub fn stratum(&self, q: &[f64]) -> Stratum {
        let chain = self.chain;
        let value = |dof: usize| q.get(dof).copied().unwrap_or(0.0);
        let repeats = self.repeat_of(q).is_some();
        if repeats {
            return Stratum::Repeat;
        }
        let inside = !chain.postures.is_empty()
            && chain
                .dofs
                .iter()
                .zip(&self.ranges)
                .all(|(&(d, angle), &(low, high))| {
                    let margin = if angle {
                        INSIDE_MARGIN_ANGLE
                    } else {
                        INSIDE_MARGIN_LENGTH
                    };
                    let v = value(d);
                    v >= low - margin && v <= high + margin
                });
        if inside {
            Stratum::Inside
        } else {
            Stratum::Outside
        }
    }
}

/// The identification postures of every tool of `model` (in tool order): what
/// [`strata`] judges against, and what `calibrate` records for `treecal verify`.
pub fn chain_postures(model: &McpcModel, identification: &[Measurement]) -> Vec<ChainPostures> {
    (0..model.tools().len())
        .map(|tool| {
            let dofs = chain_dofs(model, tool);
            let postures = identification
                .iter()
                .filter(|m| m.tool == tool)
                .map(|m| {
                    dofs.iter()
                        .map(|&(d, _)| m.q.get(d).copied().unwrap_or(0.0))
                        .collect()
                })
                .collect();
            ChainPostures { dofs, postures }
        })
        .collect()
}

/// The stratum of every validation measurement (in order), judged on the joints of its tool's
/// chain against the identification measurements of the same tool
/// ([`ChainPostures::stratum`]).
pub fn strata(
    model: &McpcModel,
    identification: &[Measurement],
    validation: &[Measurement],
) -> Vec<Stratum> {
    let chains = chain_postures(model, identification);
    let indices: Vec<PostureIndex<'_>> = chains.iter().map(ChainPostures::index).collect();
    validation
        .iter()
        .map(|m| match indices.get(m.tool) {
            Some(index) => index.stratum(&m.q),
            // A tool the model does not know: nothing to judge against.
            None => Stratum::Outside,
        })
        .collect()
}
