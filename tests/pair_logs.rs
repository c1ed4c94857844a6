//! Synthetic joint-state and tracker logs with a known clock offset, for `treecal pair`'s
//! tests: the robot holds random configurations (plateaus) joined by smooth moves, one slow
//! creep that must never be paired, jittered sample times, noise and dropped tracker rows.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use treecal::math::{Pose, Rotation, Vec3};
use treecal::tree::KinematicTree;

/// One held configuration on the true clock.
#[derive(Debug, Clone)]
pub struct Hold {
    pub start: f64,
    pub end: f64,
    pub q: Vec<f64>,
}

/// A motion: holds joined by cosine-profile moves, and slow creeps between some of them.
pub struct Motion {
    /// The tree's independent joints that move (others stay 0).
    pub moving: Vec<usize>,
    pub holds: Vec<Hold>,
    /// `(start, end)` of slow creeps (true clock).
    pub creeps: Vec<(f64, f64)>,
    pub dofs: usize,
}

impl Motion {
    /// `count` random holds (or, with `periodic`, alternating two configurations with equal
    /// holds and moves), one slow creep after the third hold.
    pub fn new(
        tree: &KinematicTree,
        moving: &[usize],
        count: usize,
        periodic: bool,
        seed: u64,
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let limits = tree.dof_limits();
        let random_q = |rng: &mut ChaCha8Rng| {
            let mut q = vec![0.0; tree.dof_count()];
            for &d in moving {
                let (lower, upper) = limits[d]
                    .as_ref()
                    .map_or((-0.8, 0.8), |l| (l.lower.max(-0.8), l.upper.min(0.8)));
                q[d] = rng.random_range(lower..upper);
            }
            q
        };
        let pair = [random_q(&mut rng), random_q(&mut rng)];
        let mut holds = Vec::new();
        let mut creeps = Vec::new();
        let mut t = 0.0;
        for k in 0..count {
            let q = if periodic {
                pair[k % 2].clone()
            } else {
                random_q(&mut rng)
            };
            let hold = if periodic {
                2.0
            } else {
                rng.random_range(1.8..3.5)
            };
            holds.push(Hold {
                start: t,
                end: t + hold,
                q,
            });
            t += hold;
            if k == 2 && !periodic {
                // 1.5 deg/s on every moving joint for 3 s: above the 0.5 deg/s threshold.
                creeps.push((t, t + 3.0));
                t += 3.0;
            }
            t += if periodic {
                1.5
            } else {
                rng.random_range(1.0..2.5)
            };
        }
        Self {
            moving: moving.to_vec(),
            holds,
            creeps,
            dofs: tree.dof_count(),
        }
    }

    /// The end of the last hold.
    pub fn duration(&self) -> f64 {
        self.holds.last().map_or(0.0, |h| h.end)
    }

    /// The configuration at true time `t`.
    pub fn q(&self, t: f64) -> Vec<f64> {
        let creep_rate = 1.5f64.to_radians();
        for (k, hold) in self.holds.iter().enumerate() {
            if t <= hold.end {
                if t >= hold.start || k == 0 {
                    return hold.q.clone();
                }
                let before = &self.holds[k - 1];
                let mut from = before.q.clone();
                let mut move_start = before.end;
                if let Some(&(s, e)) = self.creeps.iter().find(|(s, _)| *s == before.end) {
                    for &d in &self.moving {
                        from[d] += creep_rate * (t.min(e) - s);
                    }
                    if t <= e {
                        return from;
                    }
                    move_start = e;
                }
                let u = (t - move_start) / (hold.start - move_start);
                let s = 0.5 - 0.5 * (std::f64::consts::PI * u).cos();
                return from
                    .iter()
                    .zip(&hold.q)
                    .map(|(a, b)| a + s * (b - a))
                    .collect();
            }
        }
        self.holds
            .last()
            .map(|h| h.q.clone())
            .unwrap_or_else(|| vec![0.0; self.dofs])
    }
}

/// How the logs are recorded.
pub struct Recording {
    /// Joint-log clock − true time (s).
    pub joint_zero: f64,
    /// Tracker clock − true time (s).
    pub tracker_zero: f64,
    pub joint_rate: f64,
    pub tracker_rate: f64,
    /// Tracker's view of the robot base.
    pub tracker_from_base: Pose,
    /// The target (or rigid body origin) in the tool frame.
    pub marker_offset: Vec3,
    /// Fraction of tracker rows dropped at random, plus one occlusion of 0.4 s.
    pub drop: f64,
    /// The tracker records from this true time to `duration - tracker_stop`.
    pub tracker_start: f64,
    pub tracker_stop: f64,
    pub pose: bool,
    pub seed: u64,
}

impl Default for Recording {
    fn default() -> Self {
        Self {
            joint_zero: 1.7e9,
            tracker_zero: -3.9,
            joint_rate: 100.0,
            tracker_rate: 120.0,
            tracker_from_base: Pose::new(Vec3::new(2.1, -0.9, 0.7), Vec3::new(0.1, -0.08, 2.3)),
            marker_offset: Vec3::zeros(),
            drop: 0.03,
            tracker_start: 2.0,
            tracker_stop: 1.0,
            pose: true,
            seed: 7,
        }
    }
}

impl Recording {
    /// Joint-log time − tracker time.
    pub fn offset(&self) -> f64 {
        self.joint_zero - self.tracker_zero
    }

    /// Uniformly jittered sample times (true clock) at `rate` over `[from, to]`.
    fn times(rate: f64, from: f64, to: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let count = ((to - from) * rate) as usize;
        (0..count)
            .map(|k| from + (k as f64 + rng.random_range(-0.2..0.2)) / rate)
            .collect()
    }

    /// The joint-log CSV (`time,<names>` of the joints `dofs`, radians, noise 1e-5 rad on
    /// the moving joints).
    pub fn joint_csv(&self, motion: &Motion, dofs: &[usize], names: &[String]) -> String {
        let mut out = format!("time,{}\n", names.join(","));
        for (t, q) in self.joint_samples(motion) {
            let values: Vec<String> = dofs.iter().map(|&d| format!("{}", q[d])).collect();
            out += &format!("{:.6},{}\n", t, values.join(","));
        }
        out
    }

    /// Joint samples: (joint-log time, q with noise).
    pub fn joint_samples(&self, motion: &Motion) -> Vec<(f64, Vec<f64>)> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        Self::times(self.joint_rate, 0.0, motion.duration(), &mut rng)
            .into_iter()
            .map(|t| {
                let mut q = motion.q(t);
                for &d in &motion.moving {
                    let noise: f64 = StandardNormal.sample(&mut rng);
                    q[d] += 1e-5 * noise;
                }
                (t + self.joint_zero, q)
            })
            .collect()
    }

    /// The tracker CSV in mm with the given header names for `time,x,y,z,qw,qx,qy,qz`.
    pub fn tracker_csv(
        &self,
        motion: &Motion,
        tree: &KinematicTree,
        tool: &str,
        header: [&str; 8],
    ) -> String {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed + 1);
        let tool = tree.link_id(tool).unwrap();
        let columns = if self.pose { 8 } else { 4 };
        let mut out = format!("# units: length=mm\n{}\n", header[..columns].join(","));
        let from = self.tracker_start;
        let to = motion.duration() - self.tracker_stop;
        let occlusion = motion.holds.get(4).map_or(f64::INFINITY, |h| h.start + 0.5);
        for t in Self::times(self.tracker_rate, from, to, &mut rng) {
            let time = format!("{:.6}", t + self.tracker_zero);
            if rng.random_range(0.0..1.0) < self.drop || (occlusion..occlusion + 0.4).contains(&t) {
                out += &format!("{time}{}\n", ",".repeat(columns - 1));
                continue;
            }
            let pose = self.tracker_from_base
                * tree.link_pose(tool, &motion.q(t)).unwrap()
                * nalgebra::Translation3::from(self.marker_offset);
            let mut noise = || -> f64 { StandardNormal.sample(&mut rng) };
            let p = pose.translation.vector * 1e3 + Vec3::new(noise(), noise(), noise()) * 0.03;
            out += &format!("{time},{:.4},{:.4},{:.4}", p.x, p.y, p.z);
            if self.pose {
                let wobble =
                    Rotation::from_scaled_axis(Vec3::new(noise(), noise(), noise()) * 1e-4);
                let q = (pose.rotation * wobble).into_inner();
                out += &format!(",{:.8},{:.8},{:.8},{:.8}", q.w, q.i, q.j, q.k);
            }
            out += "\n";
        }
        out
    }
}
