//! What [`export_urdf_with`](super::export_urdf_with) does with a calibrated tool frame that a
//! URDF cannot carry exactly, and what it tells about it.
//!
//! A URDF joint turns its child link about an axis through the child's origin. A tool link
//! that is itself the child of a revolute joint (a palm on the wrist joint) can therefore only
//! be exported while its calibrated origin lies on the joint axis. Calibrated from noisy data it
//! almost never does exactly; the export then either drops the off-axis offset (the tool link
//! moves onto the axis, its orientation kept) when the offset is within the calibration's own
//! uncertainty, or, asked to, leaves the tool link where its joint puts it on the calibrated
//! chain (its meshes and inertia with it) and adds a fixed child link `<tool>_marker` at the
//! exact tool frame, as for a tool link with children. See `docs/export.md`.

use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::tree::KinematicTree;
use std::collections::BTreeMap;

/// How far (m) a tool link's origin may sit off the axis of the movable joint that carries it.
/// A URDF joint turns its child link about an axis through the child's origin, so a tool link
/// that is itself the child of a revolute joint can only be exported while it stays on the axis.
pub const ON_AXIS_TOLERANCE: f64 = 1e-9;

/// How many standard deviations of the tool origin an off-axis offset may be and still be
/// dropped: 3σ, so a tool that truly sits on the axis is exported without an added link in
/// all but 0.3 % of calibrations, while an offset the data resolve is never silently lost.
pub const DROPPED_OFFSET_SIGMAS: f64 = 3.0;

/// Inputs of an export beyond the model.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExportOptions {
    /// Per tool link name, the largest off-axis offset (m) that may be dropped: the
    /// calibration's own uncertainty of the tool origin ([`Self::with_uncertainty`]). Tools
    /// not listed get [`ON_AXIS_TOLERANCE`].
    pub tool_tolerances: BTreeMap<String, f64>,
    /// Add a fixed child link `<tool>_marker` carrying the exact calibrated tool frame under
    /// every tool link whose offset is too large to drop, the tool link left where its joint
    /// puts it (instead of refusing).
    pub add_tool_links: bool,
}

impl ExportOptions {
    /// Options whose per-tool tolerance is [`DROPPED_OFFSET_SIGMAS`] times the standard
    /// deviation of the tool origin's position, from the standard deviations of `model`'s
    /// parameters (`std_devs` in [`McpcModel::parameter_layout`] order, as
    /// `CalibrationRun::parameters` lists them): `σ² = σx² + σy² + σz² + |t|²·(σα² + σβ² + σγ²)`
    /// with `t = (x, y, z)` the calibrated tool offset (first order, correlations ignored).
    /// A tool whose x, y or z has no standard deviation gets no tolerance; an angle without
    /// one (held at its starting value, e.g. from position-only data) counts as exact.
    pub fn with_uncertainty(
        tree: &KinematicTree,
        model: &McpcModel,
        std_devs: &[Option<f64>],
        add_tool_links: bool,
    ) -> Self {
        let values = model.parameters();
        let mut tool_tolerances = BTreeMap::new();
        for (index, tool) in model.tools().iter().enumerate() {
            let offset = model.tool_parameter_offset(index);
            let (Some(angles), Some(lengths)) = (
                std_devs.get(offset..offset + 3),
                std_devs.get(offset + 3..offset + 6),
            ) else {
                continue;
            };
            let Some(length_variance) = lengths
                .iter()
                .map(|s| s.filter(|s| s.is_finite()).map(|s| s * s))
                .sum::<Option<f64>>()
            else {
                continue;
            };
            let lever = values
                .get(offset + 3..offset + 6)
                .map_or(0.0, |t| t.iter().map(|v| v * v).sum::<f64>());
            let angle_variance: f64 = angles
                .iter()
                .map(|s| s.filter(|s| s.is_finite()).map_or(0.0, |s| s * s))
                .sum();
            let sigma = (length_variance + lever * angle_variance).sqrt();
            tool_tolerances.insert(
                tree.link(tool.link).name.clone(),
                DROPPED_OFFSET_SIGMAS * sigma,
            );
        }
        ExportOptions {
            tool_tolerances,
            add_tool_links,
        }
    }

    /// The largest off-axis offset (m) that may be dropped for tool link `name`.
    pub fn tolerance(&self, name: &str) -> f64 {
        self.tool_tolerances
            .get(name)
            .copied()
            .unwrap_or(ON_AXIS_TOLERANCE)
            .max(ON_AXIS_TOLERANCE)
    }
}

/// A tool offset the export left out: the tool link was moved onto the axis of the joint that
/// carries it, keeping its orientation, because the offset is within the calibration's
/// uncertainty.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DroppedOffset {
    /// The tool link.
    pub tool: String,
    /// The revolute joint whose child it is.
    pub joint: String,
    /// How far the calibrated tool origin lies off the joint axis (mm); the orientation is
    /// exported exactly, so this is the whole difference between the file and the model.
    pub offset_mm: f64,
    /// The tolerance it was compared with (mm).
    pub tolerance_mm: f64,
}

/// Why the export added a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AddedReason {
    /// The calibrated tool origin lies off the axis of the joint that moves the tool link, a
    /// leaf ([`ExportOptions::add_tool_links`]): the tool link keeps its place on the
    /// calibrated chain, the tool frame goes into `<tool>_marker`.
    OffAxis,
    /// The tool link has child links, which must not move with the measured frame: the
    /// measured (marker) frame goes into a new link `<tool>_marker` instead.
    Marker,
    /// A measured point (a marker link added at load time, not in the URDF text).
    Point,
}

/// A fixed link the export added below a link of the URDF, at an exact calibrated tool frame.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AddedToolLink {
    /// The model's tool link whose calibrated frame the added link carries (for
    /// [`AddedReason::Point`] the added link itself).
    pub tool: String,
    /// The added link; its fixed joint is `<link>_joint`.
    pub link: String,
    /// The URDF link it hangs from.
    pub parent: String,
    /// Why it was added.
    pub reason: AddedReason,
    /// [`AddedReason::OffAxis`]: how far the calibrated tool origin lies off the joint axis
    /// (mm); otherwise the distance of the added link from its parent link's origin (mm).
    pub offset_mm: f64,
    /// The added link's pose in its parent link frame.
    #[serde(skip)]
    pub parent_from_link: Pose,
    /// Its origin in the parent link frame, as in the URDF (m).
    pub xyz: [f64; 3],
    /// Its roll, pitch, yaw in the parent link frame, as in the URDF (rad).
    pub rpy: [f64; 3],
}

/// The XML of the links in `added`, to go right before `</robot>`, each with a comment that
/// says why it is there; `indent` is the indentation of the file's other links.
pub(super) fn added_links_xml(added: &[AddedToolLink], indent: &str) -> String {
    let escape = |name: &str| {
        name.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
    };
    let mut out = String::new();
    for link in added {
        let (t, r) = (link.xyz, link.rpy);
        let why = match link.reason {
            AddedReason::OffAxis => format!(
                "the calibrated frame of tool '{}', whose origin lies {:.4} mm off the axis of the joint that moves the tool link (a URDF joint cannot express that); the tool link keeps its place on the calibrated arm",
                link.tool, link.offset_mm
            ),
            AddedReason::Marker => format!(
                "the calibrated measured (marker) frame of tool '{}', kept apart so that the links below the tool stay where the robot's description puts them",
                link.tool
            ),
            AddedReason::Point => {
                "a measured point (marker) on the link, at its calibrated position".to_owned()
            }
        };
        // `--` may not appear inside an XML comment.
        let why = why.replace("--", "- -");
        out += &format!(
            "{indent}<!-- Added by treecal export: {why}. -->\n\
             {indent}<link name=\"{name}\"/>\n\
             {indent}<joint name=\"{name}_joint\" type=\"fixed\">\n\
             {indent}  <parent link=\"{parent}\"/>\n\
             {indent}  <child link=\"{name}\"/>\n\
             {indent}  <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>\n\
             {indent}</joint>\n",
            t[0],
            t[1],
            t[2],
            r[0],
            r[1],
            r[2],
            parent = escape(&link.parent),
            name = escape(&link.link),
        );
    }
    out
}
