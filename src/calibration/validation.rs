//! Where each validation configuration lies relative to the identification data: a repeat of
//! an identification posture, a new posture inside the identification joint ranges, or one
//! outside them (`docs/calibration.md`, "Errors before and after"). Every validation row is
//! counted in the figures; the strata tell how far the result carries.

use crate::kinematics::{FrameKind, McpcModel};
use crate::measurement::Measurement;
use rayon::prelude::*;
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
        // In parallel (8·10⁵ postures a tool at 10⁶ configurations), in the total order
        // (−0 below +0): the smallest and largest value whatever order they are met in.
        let lower = |a: f64, b: f64| if b.total_cmp(&a).is_lt() { b } else { a };
        let upper = |a: f64, b: f64| if b.total_cmp(&a).is_gt() { b } else { a };
        (0..self.dofs.len())
            .map(|k| {
                self.postures.par_iter().map(|p| (p[k], p[k])).reduce(
                    || (f64::INFINITY, f64::NEG_INFINITY),
                    |(l, h), (a, b)| (lower(l, a), upper(h, b)),
                )
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
        // The (at most three) joints that spread the postures over the most tolerances: binned
        // on them, a repeat is searched among the few postures in the cells around `q` (two
        // keys left ~40 postures per cell at 10⁶ configurations: a look-up cost grew with N).
        let spread = |k: usize| (ranges[k].1 - ranges[k].0) / repeat_tolerance(self.dofs[k].1);
        let mut by_spread: Vec<usize> = (0..self.dofs.len()).collect();
        by_spread.sort_by(|&a, &b| spread(b).total_cmp(&spread(a)).then(a.cmp(&b)));
        by_spread.truncate(KEYS);
        let mut index = PostureIndex {
            chain: self,
            ranges,
            keys: by_spread,
            order: Vec::new(),
            cells: Vec::new(),
            groups: Vec::new(),
        };
        // Every key distinct (ties by index): the unstable parallel sort gives one order.
        let mut sorted: Vec<(Cell, usize)> = self
            .postures
            .par_iter()
            .enumerate()
            .map(|(i, p)| (index.cell(p, |k| k), i))
            .collect();
        sorted.par_sort_unstable();
        (index.cells, index.order) = sorted.into_iter().unzip();
        let mut start = 0;
        for group in index.cells.chunk_by(|a, b| a[..2] == b[..2]) {
            let end = start + group.len();
            index.groups.push(([group[0][0], group[0][1]], start..end));
            start = end;
        }
        index
    }
}

/// The joints a [`PostureIndex`] bins the postures along (at most).
const KEYS: usize = 3;

/// A posture's cell: its bin on each key joint (0 for a missing key).
type Cell = [i64; KEYS];

fn repeat_tolerance(angle: bool) -> f64 {
    if angle {
        REPEAT_ANGLE
    } else {
        REPEAT_LENGTH
    }
}

/// [`ChainPostures`] prepared for many look-ups ([`ChainPostures::index`]): the ranges computed
/// once, the postures sorted by their cell on (at most) three joints, each cell twice the repeat
/// tolerance wide, and grouped by their bins on the first two. A look-up finds the 9 groups
/// around `q` by a binary search of the groups' (sorted) bins and searches the third bin within
/// each, with the same result as a scan of all. Many look-ups are cheapest in the order of
/// their cells (`places` sorts them so): neighbouring queries then
/// read the same groups and postures from the cache instead of memory.
#[derive(Debug, Clone)]
pub struct PostureIndex<'a> {
    chain: &'a ChainPostures,
    ranges: Vec<(f64, f64)>,
    /// The positions in `chain.dofs` of the joints the postures are binned along.
    keys: Vec<usize>,
    /// Posture indices, sorted by their cells (ties by index).
    order: Vec<usize>,
    /// Those cells, in the same order.
    cells: Vec<Cell>,
    /// The range of `cells` on each pair of bins of the first two key joints, sorted by the
    /// pair.
    groups: Vec<([i64; 2], std::ops::Range<usize>)>,
}

impl PostureIndex<'_> {
    /// The cell of a point whose value of `chain.dofs[k]` is `value(position of k)`: on each
    /// key joint, the value in units of twice its repeat tolerance, rounded down (0 for a
    /// missing key). Two values within the tolerance are at most one cell apart.
    fn cell(&self, point: &[f64], position: impl Fn(usize) -> usize) -> Cell {
        let on = |slot: usize| {
            self.keys.get(slot).map_or(0, |&k| {
                let v = point.get(position(k)).copied().unwrap_or(0.0);
                // `as` saturates (and maps NaN to 0): such a value never repeats a posture.
                (v / (2.0 * repeat_tolerance(self.chain.dofs[k].1))).floor() as i64
            })
        };
        [on(0), on(1), on(2)]
    }

    /// The cell of a configuration `q` of this tool: look-ups in the order of their cells
    /// share the cache.
    fn query_cell(&self, q: &[f64]) -> Cell {
        self.cell(q, |k| self.chain.dofs[k].0)
    }

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
        // Every candidate lies in the cells one either side of `q`'s on every key joint; the
        // full test decides, exactly as a scan of every posture would.
        let [a, b, c] = self.query_cell(q);
        let (c_low, c_high) = (c.saturating_sub(1), c.saturating_add(1));
        let mut first: Option<usize> = None;
        for (da, db) in (-1..=1).flat_map(|da| (-1..=1).map(move |db| (da, db))) {
            let (row, column) = (a.saturating_add(da), b.saturating_add(db));
            let Ok(found) = self.groups.binary_search_by(|(k, _)| k.cmp(&[row, column])) else {
                continue;
            };
            let group = &self.groups[found].1;
            let cells = &self.cells[group.clone()];
            let start = group.start + cells.partition_point(|c| c[2] < c_low);
            let end = group.start + cells.partition_point(|c| c[2] <= c_high);
            let found = self.order[start.min(end)..end]
                .iter()
                .copied()
                .filter(|&i| repeats_posture(&chain.postures[i]))
                .min();
            first = match (first, found) {
                (Some(x), Some(y)) => Some(x.min(y)),
                (x, y) => x.or(y),
            };
        }
        first
    }

    /// Where a configuration `q` of this tool lies ([`ChainPostures::stratum`]).
    pub fn stratum(&self, q: &[f64]) -> Stratum {
        self.place(q).0
    }

    /// Where a configuration `q` of this tool lies and the posture it repeats
    /// ([`Self::repeat_of`]): one look-up for both.
    pub fn place(&self, q: &[f64]) -> (Stratum, Option<usize>) {
        let chain = self.chain;
        let value = |dof: usize| q.get(dof).copied().unwrap_or(0.0);
        let repeat = self.repeat_of(q);
        if repeat.is_some() {
            return (Stratum::Repeat, repeat);
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
            (Stratum::Inside, None)
        } else {
            (Stratum::Outside, None)
        }
    }
}

/// The identification postures of every tool of `model` (in tool order): what
/// [`strata`] judges against, and what `calibrate` records for `treecal verify`.
pub fn chain_postures(model: &McpcModel, identification: &[Measurement]) -> Vec<ChainPostures> {
    (0..model.tools().len())
        .map(|tool| {
            let dofs = chain_dofs(model, tool);
            // In parallel (rayon's collect keeps the order): a posture per row.
            let postures = identification
                .par_iter()
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
    places(model, identification, validation)
        .into_iter()
        .map(|(stratum, _)| stratum)
        .collect()
}

/// The stratum of every validation measurement (in order, as [`strata`]) with the
/// identification row (its index in `identification`) whose posture it repeats: the first
/// row of its tool at that posture ([`PostureIndex::repeat_of`]; none for a tool whose chain
/// has no joint, where every row is the same posture).
pub fn places(
    model: &McpcModel,
    identification: &[Measurement],
    validation: &[Measurement],
) -> Vec<(Stratum, Option<usize>)> {
    let chains = chain_postures(model, identification);
    let indices: Vec<PostureIndex<'_>> = chains.iter().map(ChainPostures::index).collect();
    // Per tool, the index of its identification rows in the order of its chain's postures.
    let rows_of: Vec<Vec<usize>> = (0..chains.len())
        .map(|tool| {
            let of_tool = identification.par_iter().enumerate();
            of_tool
                .filter(|(_, m)| m.tool == tool)
                .map(|(i, _)| i)
                .collect()
        })
        .collect();
    // In parallel, in the order of the rows' cells (neighbouring look-ups share the cache;
    // in validation order each one read its groups and postures from memory), then put back
    // in validation order.
    let mut queries: Vec<(usize, [i64; 3], usize)> = validation
        .par_iter()
        .enumerate()
        .map(|(i, m)| {
            let cell = indices.get(m.tool).map_or([0; 3], |x| x.query_cell(&m.q));
            (m.tool, cell, i)
        })
        .collect();
    queries.par_sort_unstable();
    let found: Vec<(Stratum, Option<usize>)> = queries
        .par_iter()
        .map(|&(tool, _, i)| match indices.get(tool) {
            Some(index) => {
                let (stratum, repeat) = index.place(&validation[i].q);
                let moves = !chains[tool].dofs.is_empty();
                (stratum, repeat.filter(|_| moves).map(|p| rows_of[tool][p]))
            }
            // A tool the model does not know: nothing to judge against.
            None => (Stratum::Outside, None),
        })
        .collect();
    let mut places = vec![(Stratum::Outside, None); validation.len()];
    for (&(_, _, i), place) in queries.iter().zip(found) {
        places[i] = place;
    }
    places
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    /// The first posture a scan of every posture finds `q` to repeat.
    fn scanned(chain: &ChainPostures, q: &[f64]) -> Option<usize> {
        chain.postures.iter().position(|posture| {
            chain.dofs.iter().zip(posture).all(|(&(d, angle), &p)| {
                (p - q.get(d).copied().unwrap_or(0.0)).abs() <= repeat_tolerance(angle)
            })
        })
    }

    /// The ranges are each joint's smallest and largest value, −0 below +0, on any number of
    /// threads (they are computed in parallel).
    #[test]
    fn ranges_are_the_extremes_on_any_number_of_threads() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut postures: Vec<Vec<f64>> = (0..5000)
            .map(|_| vec![rng.random_range(-2.0..3.0), rng.random_range(0.0..1.0)])
            .collect();
        postures[17][1] = -0.0;
        postures[4000][1] = 0.0;
        let chain = ChainPostures {
            dofs: vec![(0, true), (1, false)],
            postures,
        };
        let serial: Vec<(f64, f64)> = (0..2)
            .map(|k| {
                let values = chain.postures.iter().map(|p| p[k]);
                let low = values.clone().min_by(|a, b| a.total_cmp(b)).expect("low");
                (low, values.max_by(|a, b| a.total_cmp(b)).expect("high"))
            })
            .collect();
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            let ranges = pool.install(|| chain.ranges());
            let bits = |r: &[(f64, f64)]| -> Vec<(u64, u64)> {
                r.iter().map(|(a, b)| (a.to_bits(), b.to_bits())).collect()
            };
            assert_eq!(bits(&ranges), bits(&serial), "{threads} threads");
        }
        assert_eq!(serial[1].0.to_bits(), (-0.0f64).to_bits());
    }

    /// `places` (its look-ups sorted by cell, then put back) gives every validation row, in
    /// validation order, what a look-up of that row alone gives: on two tools, with repeats of
    /// identification postures, near misses, new postures and a tool the model does not know.
    #[test]
    fn places_are_the_rows_own_look_ups_in_validation_order() {
        let robot = crate::calibration::test_problems::robonaut();
        let model = &robot.0;
        let identification = crate::calibration::test_problems::problem(&robot, 300, true);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut validation: Vec<Measurement> = (0..900)
            .map(|i| {
                let mut m = identification[(i * 7) % identification.len()].clone();
                let shift = [0.0, 0.004, 0.03, 1.0][i % 4];
                for q in &mut m.q {
                    *q += rng.random_range(-shift..=shift);
                }
                m
            })
            .collect();
        validation[17].tool = 9;
        let placed = places(model, &identification, &validation);
        let chains = chain_postures(model, &identification);
        let indices: Vec<PostureIndex<'_>> = chains.iter().map(ChainPostures::index).collect();
        let mut counts = [0; 3];
        for (i, (m, &(stratum, repeat))) in validation.iter().zip(&placed).enumerate() {
            let Some(index) = indices.get(m.tool) else {
                assert_eq!((stratum, repeat), (Stratum::Outside, None), "row {i}");
                continue;
            };
            let (own, posture) = index.place(&m.q);
            assert_eq!(stratum, own, "row {i}");
            let rows: Vec<usize> = (0..identification.len())
                .filter(|&r| identification[r].tool == m.tool)
                .collect();
            assert_eq!(repeat, posture.map(|p| rows[p]), "row {i}");
            if let Some(r) = repeat {
                assert_eq!(identification[r].tool, m.tool);
            }
            counts[stratum as usize] += 1;
        }
        assert!(counts.iter().all(|&c| c > 50), "{counts:?}");
    }

    /// The binned index finds the same repeat (the first one) as a scan of every posture, on
    /// postures crowded within a few tolerances so that repeats, near misses at the tolerance
    /// and duplicates are common; with one, two and four joints, revolute and prismatic.
    #[test]
    fn the_index_finds_what_a_scan_finds() {
        let mut rng = ChaCha8Rng::seed_from_u64(24);
        for dofs in [
            vec![(0, true)],
            vec![(1, false), (0, true)],
            vec![(0, true), (2, false), (3, true), (1, true)],
        ] {
            // About three tolerances per posture along each joint: crowded, not all one cell.
            let reach = 3.0 * 400f64.powf(1.0 / dofs.len() as f64) / 2.0;
            let span = |angle: bool| reach * repeat_tolerance(angle);
            let postures: Vec<Vec<f64>> = (0..400)
                .map(|_| {
                    dofs.iter()
                        .map(|&(_, a)| rng.random_range(-span(a)..span(a)))
                        .collect()
                })
                .collect();
            let chain = ChainPostures { dofs, postures };
            let index = chain.index();
            let (mut repeats, mut misses) = (0, 0);
            for trial in 0..2000 {
                let mut q = vec![0.0; 4];
                let near = &chain.postures[trial % chain.postures.len()];
                for (&(d, angle), &p) in chain.dofs.iter().zip(near) {
                    let tolerance = repeat_tolerance(angle);
                    q[d] = p + rng.random_range(-1.3 * tolerance..1.3 * tolerance);
                }
                let expected = scanned(&chain, &q);
                assert_eq!(index.repeat_of(&q), expected, "q = {q:?}");
                match expected {
                    Some(_) => repeats += 1,
                    None => misses += 1,
                }
            }
            assert!(
                repeats > 100 && misses > 100,
                "{repeats} repeats, {misses} misses"
            );
        }
    }
}
