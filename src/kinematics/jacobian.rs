//! The analytic identification Jacobian of the MCPC model (paper section 2.3, eq. (5)–(17)).
//!
//! For a tool pose `T` and a parameter `e`, the column `∂T/∂e` is a twist in the base frame:
//! the first three rows are the change of the tool position (m per unit of `e`), the last
//! three the small rotation (rad per unit of `e`) with `R_measured ≈ (I + [δ]×)·R_model`. This
//! is eq. (14)–(17) of the paper written directly in the base frame: α of frame i rotates
//! everything after it about the x axis of `P·Rz(φ)`, β about the y axis of
//! `P·Rz(φ)·Rx(α)` — both through the origin of `P`, the frame the constant part of frame i is
//! applied to (the previous frame moved by its joint) — and x, y translate along the frame's
//! own x and y. Tool parameters work the same way, with γ about the tool's z and x, y, z along
//! the tool's axes. The same formulas hold on a deflected chain ([`ChainFrames`] from the
//! flexibility model), which keeps the Jacobian accurate when the robot bends.
//! See `docs/identification.md`.

use super::forward::JointMotions;
use super::mcpc::{FrameKind, McpcModel};
use crate::math::{Pose, Transform, Vec3};
use nalgebra::DMatrix;

/// A tool pose with its identification Jacobian.
#[derive(Debug, Clone)]
pub struct ToolJacobian {
    /// The tool pose in the base frame.
    pub pose: Pose,
    /// 6 × [`McpcModel::parameter_count`]: rows x, y, z (m) then rotation x, y, z (rad), in the
    /// base frame; zero columns for parameters off the tool's chain.
    pub jacobian: DMatrix<f64>,
}

/// The frames of one configuration that the Jacobian is built from, in the measurement frame.
/// Reusable: [`McpcModel::chain_frames_into`] and [`McpcModel::tool_jacobian_into`] refill
/// its buffers without allocating.
#[derive(Debug, Clone, Default)]
pub struct ChainFrames {
    /// For each MCPC frame, the frame its constant part is applied to (`P`: the previous frame
    /// moved by its joint, and by any deformation).
    pub previous: Vec<Transform>,
    /// Each MCPC frame Σᵢ = P·constant.
    pub frames: Vec<Transform>,
    /// For each tool, the frame its constant part is applied to.
    pub tool_previous: Vec<Transform>,
    /// Each tool frame.
    pub tools: Vec<Transform>,
    /// The joint values with their sines and cosines.
    pub(crate) motions: JointMotions,
    /// Per frame, `∂θ/∂(joint-error term)` (empty without joint errors).
    pub(crate) joint_error_factors: Vec<[f64; 4]>,
    /// The root in the measurement frame at the configuration, where it moves (a reference
    /// link other than the root); `None`: the model's constant measurement frame.
    pub(crate) world_from_root: Option<Transform>,
}

thread_local! {
    /// The chain of [`McpcModel::tool_jacobians`] (not reentrant: nothing it calls uses it).
    static SCRATCH: std::cell::RefCell<ChainFrames> = std::cell::RefCell::default();
}

impl McpcModel {
    /// The rigid chain at configuration `q`.
    pub fn chain_frames(&self, q: &[f64]) -> ChainFrames {
        let mut chain = ChainFrames::default();
        self.chain_frames_into(q, &mut chain);
        chain
    }

    /// The rigid chain at configuration `q`, written into `chain`'s buffers (no allocation
    /// once they have grown). Each frame's joint motion is applied once per child.
    pub fn chain_frames_into(&self, q: &[f64], chain: &mut ChainFrames) {
        self.size_chain(chain);
        chain.motions.fill(self, q);
        self.joint_error_factors(q, &mut chain.joint_error_factors);
        chain.world_from_root = self.moving_root(q);
        self.set_chain_frames(0..self.frames().len(), chain);
        for tool in 0..self.tools().len() {
            self.set_chain_tool(tool, chain);
        }
    }

    /// The root in the measurement frame at `q` if it moves (a reference link), else `None`.
    fn moving_root(&self, q: &[f64]) -> Option<Transform> {
        self.reference()
            .is_some()
            .then(|| self.world_from_root_transform(q))
    }

    /// The frame the root-side frames and tools hang from: the root in the measurement frame.
    #[inline]
    fn chain_root(&self, chain: &ChainFrames) -> Transform {
        chain
            .world_from_root
            .unwrap_or(*self.world_from_base_transform())
    }

    /// Sizes `chain`'s buffers for this model (new entries are identities; entries not
    /// recomputed keep what they held).
    fn size_chain(&self, chain: &mut ChainFrames) {
        let (frames, tools) = (self.frames().len(), self.tools().len());
        for (buffer, size) in [
            (&mut chain.previous, frames),
            (&mut chain.frames, frames),
            (&mut chain.tool_previous, tools),
            (&mut chain.tools, tools),
        ] {
            buffer.resize(size, Transform::identity());
        }
    }

    /// `previous` and `frames` of `frame`, from its parent's (already set) frame and
    /// `chain.motions` (filled at the configuration). `last` is the frame set just before, if
    /// any: when it is the parent it is taken from there rather than read back from
    /// `chain.frames`, which it has only just been written to (reading it back stalls on the
    /// store). Returns the frame.
    #[inline(always)]
    fn set_chain_frame(
        &self,
        frame: usize,
        chain: &mut ChainFrames,
        last: Option<&(usize, Transform)>,
    ) -> Transform {
        let previous = match self.frames()[frame].parent {
            Some(p) => match last {
                Some((index, parent)) if *index == p => chain.motions.apply(self, p, parent),
                _ => chain.motions.apply(self, p, &chain.frames[p]),
            },
            None => self.chain_root(chain),
        };
        let sigma = previous.then(self.frame_constant(frame));
        chain.frames[frame] = sigma;
        chain.previous[frame] = previous;
        sigma
    }

    /// [`Self::set_chain_frame`] of `frames` in order (parents before their children).
    #[inline(always)]
    fn set_chain_frames(&self, frames: impl Iterator<Item = usize>, chain: &mut ChainFrames) {
        let mut last = None;
        for frame in frames {
            let sigma = self.set_chain_frame(frame, chain, last.as_ref());
            last = Some((frame, sigma));
        }
    }

    /// `tool_previous` and `tools` of `tool`, from its last frame (already set).
    #[inline]
    fn set_chain_tool(&self, tool: usize, chain: &mut ChainFrames) {
        let previous = match self.tools()[tool].parent {
            Some(p) => chain.motions.apply(self, p, &chain.frames[p]),
            None => self.chain_root(chain),
        };
        chain.tools[tool] = previous.then(self.tool_constant(tool));
        chain.tool_previous[tool] = previous;
    }

    /// Writes the Jacobian columns of tool `tool` into `jacobian` (6 × parameter_count, zeroed
    /// by the caller), one whole column (6 contiguous values) at a time.
    fn fill_tool_jacobian(&self, tool: usize, chain: &ChainFrames, jacobian: &mut DMatrix<f64>) {
        debug_assert_eq!(jacobian.nrows(), 6);
        let tip = chain.tools[tool].translation;
        let data = jacobian.as_mut_slice();
        let mut put = |column: usize, values: [f64; 6]| {
            data[6 * column..6 * column + 6].copy_from_slice(&values);
        };
        let rotation = |axis: Vec3, through: &Vec3| {
            let linear = axis.cross(&(tip - through));
            [linear.x, linear.y, linear.z, axis.x, axis.y, axis.z]
        };
        let translation = |d: Vec3| [d.x, d.y, d.z, 0.0, 0.0, 0.0];
        for &frame in self.tool_chain(tool) {
            let previous = &chain.previous[frame];
            let [alpha_axis, beta_axis] = self.frame_axes(frame);
            let offset = self.frame_parameter_offset(frame);
            put(
                offset,
                rotation(previous.rotation * alpha_axis, &previous.translation),
            );
            put(
                offset + 1,
                rotation(previous.rotation * beta_axis, &previous.translation),
            );
            // Translations along the frame's own x and y (revolute frames only).
            if self.frames()[frame].kind == FrameKind::Revolute {
                let axes = &chain.frames[frame].rotation;
                put(offset + 2, translation(axes.column(0).into_owned()));
                put(offset + 3, translation(axes.column(1).into_owned()));
            }
        }
        let last = &chain.tool_previous[tool];
        let axes = self.tool_axes(tool);
        let offset = self.tool_parameter_offset(tool);
        for (k, axis) in axes.iter().enumerate() {
            put(
                offset + k,
                rotation(last.rotation * axis, &last.translation),
            );
        }
        // Translations along the tool's x, y, z.
        let tool_axes = &chain.tools[tool].rotation;
        for k in 0..3 {
            put(
                offset + 3 + k,
                translation(tool_axes.column(k).into_owned()),
            );
        }
        self.fill_extension_columns(
            tool,
            &tip,
            &chain.frames,
            &chain.joint_error_factors,
            jacobian.as_mut_slice(),
        );
        if self.reference().is_some() {
            self.add_reference_columns(
                &tip,
                &chain.previous,
                &chain.frames,
                &chain.joint_error_factors,
                jacobian.as_mut_slice(),
            );
        }
    }

    /// Tool poses and identification Jacobians of every tool on a given chain.
    pub fn jacobians_on(&self, chain: &ChainFrames) -> Vec<ToolJacobian> {
        (0..self.tools().len())
            .map(|tool| {
                let mut jacobian = DMatrix::zeros(6, self.parameter_count());
                self.fill_tool_jacobian(tool, chain, &mut jacobian);
                ToolJacobian {
                    pose: chain.tools[tool].to_pose(),
                    jacobian,
                }
            })
            .collect()
    }

    /// [`McpcModel::tool_jacobians`] into `out`, its matrices reused (no allocation once they
    /// have their size): the same poses and matrices bit for bit.
    pub fn tool_jacobians_reusing(&self, q: &[f64], out: &mut Vec<ToolJacobian>) {
        SCRATCH.with(|scratch| {
            let mut chain = scratch.borrow_mut();
            self.chain_frames_into(q, &mut chain);
            out.resize_with(self.tools().len(), || ToolJacobian {
                pose: Pose::identity(),
                jacobian: DMatrix::zeros(0, 0),
            });
            for (tool, out) in out.iter_mut().enumerate() {
                self.reset_jacobian(tool, &mut out.jacobian);
                self.fill_tool_jacobian(tool, &chain, &mut out.jacobian);
                out.pose = chain.tools[tool].to_pose();
            }
        })
    }

    /// Tool pose and identification Jacobian of tool `tool` at configuration `q`.
    pub fn tool_jacobian(&self, tool: usize, q: &[f64]) -> ToolJacobian {
        let mut jacobian = DMatrix::zeros(6, self.parameter_count());
        let pose = self.tool_jacobian_into(tool, q, &mut ChainFrames::default(), &mut jacobian);
        ToolJacobian { pose, jacobian }
    }

    /// [`McpcModel::tool_jacobian`] into caller-provided buffers (no allocation once they
    /// have their size): only the frames on the tool's own chain are computed; `jacobian` is
    /// resized to 6 × parameter_count if needed and overwritten. Returns the tool pose.
    pub fn tool_jacobian_into(
        &self,
        tool: usize,
        q: &[f64],
        chain: &mut ChainFrames,
        jacobian: &mut DMatrix<f64>,
    ) -> Pose {
        self.size_chain(chain);
        let frames = [self.reference_chain(), self.tool_chain(tool)];
        chain.motions.fill_frames(self, q, &frames);
        self.joint_error_factors(q, &mut chain.joint_error_factors);
        chain.world_from_root = self.moving_root(q);
        self.set_chain_frames(frames.iter().flat_map(|f| f.iter().copied()), chain);
        self.set_chain_tool(tool, chain);
        self.reset_jacobian(tool, jacobian);
        self.fill_tool_jacobian(tool, chain, jacobian);
        chain.tools[tool].to_pose()
    }

    /// [`McpcModel::tool_jacobians`] into caller-provided buffers (no allocation once they
    /// have their size): `jacobians` gets one 6 × parameter_count matrix per tool, overwritten;
    /// the tool poses are `chain.tools`. Shared frames are computed once.
    pub fn tool_jacobians_into(
        &self,
        q: &[f64],
        chain: &mut ChainFrames,
        jacobians: &mut Vec<DMatrix<f64>>,
    ) {
        self.chain_frames_into(q, chain);
        jacobians.resize_with(self.tools().len(), || DMatrix::zeros(0, 0));
        for (tool, jacobian) in jacobians.iter_mut().enumerate() {
            self.reset_jacobian(tool, jacobian);
            self.fill_tool_jacobian(tool, chain, jacobian);
        }
    }

    /// Sizes `jacobian` to 6 × parameter_count and zeroes the columns
    /// [`Self::fill_tool_jacobian`] of `tool` does not overwrite (the buffer may hold another
    /// tool's or configuration's columns).
    fn reset_jacobian(&self, tool: usize, jacobian: &mut DMatrix<f64>) {
        if jacobian.shape() != (6, self.parameter_count()) {
            *jacobian = DMatrix::zeros(6, self.parameter_count());
            return;
        }
        // The contiguous slice: `DMatrix::fill` walks the matrix element by element.
        let data = jacobian.as_mut_slice();
        // Reference columns accumulate, and joint-error and measurement-frame columns sit
        // apart from the frames' and tools' blocks: zero everything then.
        if self.reference().is_some() || self.has_extension_columns() {
            data.fill(0.0);
            return;
        }
        // The tool's chain writes whole blocks in increasing parameter order (frames first,
        // parents before children), then the tool's 6 columns: zero the gaps between them.
        let tool_block = (self.tool_parameter_offset(tool), 6);
        let blocks = self
            .tool_chain(tool)
            .iter()
            .map(|&frame| {
                let count = self.frames()[frame].kind.parameter_count();
                (self.frame_parameter_offset(frame), count)
            })
            .chain(std::iter::once(tool_block));
        let mut cursor = 0;
        for (offset, count) in blocks {
            if offset < cursor {
                // Not in increasing order (not expected): zero everything.
                data.fill(0.0);
                return;
            }
            data[6 * cursor..6 * offset].fill(0.0);
            cursor = offset + count;
        }
        data[6 * cursor..].fill(0.0);
    }

    /// Poses and Jacobians of every tool at configuration `q`; shared frames computed once
    /// (eq. (16): the coupled branch's columns are shared by the arms).
    pub fn tool_jacobians(&self, q: &[f64]) -> Vec<ToolJacobian> {
        SCRATCH.with(|scratch| {
            let mut chain = scratch.borrow_mut();
            self.chain_frames_into(q, &mut chain);
            self.jacobians_on(&chain)
        })
    }
}
