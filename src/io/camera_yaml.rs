//! The camera file (YAML, `--cameras FILE`): the cameras (link, nominal pose, intrinsics,
//! distortion, image size, what to estimate) and the targets they see (boards and single
//! markers on links or fixed in the world, with their nominal poses).
//!
//! ```yaml
//! units: {length: m, angle: deg}      # of the poses and the board spacing (default m, rad)
//! cameras:
//!   - name: head
//!     link: head_link                   # or `world`
//!     pose: {xyz: [0.08, 0.0, 0.12], rpy: [-90, 0, -90]}   # the camera frame in the link
//!     intrinsics: {fx: 525.0, fy: 525.0, cx: 319.5, cy: 239.5}
//!     distortion: [0.05, -0.1, 0.0, 0.0, 0.0]             # k1, k2, p1, p2, k3 (OpenCV order)
//!     image: {width: 640, height: 480}
//!     estimate: [pose]                  # any of pose, intrinsics (default: pose)
//! targets:
//!   - name: left_board
//!     link: left_tool
//!     pose: {xyz: [-0.075, -0.05, 0.02], rpy: [180, 0, 0]}
//!     board: {rows: 5, columns: 7, spacing: 0.025}
//!   - name: pole_board
//!     link: world
//!     pose: {xyz: [1.5, -0.3, 0.6], rpy: [-90, 0, -90]}
//!     board: {rows: 7, columns: 10, spacing: 0.06}
//!     estimate: []                      # known in the root frame (default: [pose])
//!   - name: led
//!     link: right_tool
//!     pose: {xyz: [0, 0, 0.01], rpy: [0, 0, 0]}
//!     marker: {}
//! ```
//!
//! The camera frame is OpenCV's (z forward, x right, y down in the image). See
//! `docs/file-formats.md` and `docs/camera.md`.

use super::units::{AngleUnit, LengthUnit};
use super::yaml::parse_yaml;
use crate::camera::{CameraSpec, Intrinsics, Mount, TargetShape, TargetSpec};
use crate::error::{Error, Result};
use crate::math::{rotation_from_rpy, Pose};
use crate::tree::KinematicTree;
use nalgebra::Translation3;
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    #[serde(default)]
    units: Option<UnitsEntry>,
    cameras: Vec<CameraEntry>,
    #[serde(default)]
    targets: Vec<TargetEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UnitsEntry {
    length: String,
    angle: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseEntry {
    xyz: [f64; 3],
    rpy: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IntrinsicsEntry {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ImageEntry {
    width: f64,
    height: f64,
}

#[derive(Deserialize, PartialEq, Eq, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum Estimated {
    Pose,
    Intrinsics,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraEntry {
    name: String,
    link: String,
    pose: PoseEntry,
    intrinsics: IntrinsicsEntry,
    #[serde(default)]
    distortion: Option<[f64; 5]>,
    image: ImageEntry,
    #[serde(default)]
    estimate: Option<Vec<Estimated>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoardEntry {
    rows: usize,
    columns: usize,
    spacing: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkerEntry {}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TargetEntry {
    name: String,
    link: String,
    pose: PoseEntry,
    #[serde(default)]
    board: Option<BoardEntry>,
    #[serde(default)]
    marker: Option<MarkerEntry>,
    #[serde(default)]
    estimate: Option<Vec<Estimated>>,
}

/// The cameras and targets of a camera file, resolved against `tree`.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraFileContents {
    /// The cameras.
    pub cameras: Vec<CameraSpec>,
    /// The targets.
    pub targets: Vec<TargetSpec>,
}

/// Reads a camera file for `tree`.
pub fn read_camera_file(path: &Path, tree: &KinematicTree) -> Result<CameraFileContents> {
    let text = super::read_text(path, crate::limits::MAX_YAML_BYTES)?;
    parse_camera_file(&text, &path.display().to_string(), tree)
}

/// [`read_camera_file`] from text; `origin` names the file in messages.
pub fn parse_camera_file(
    text: &str,
    origin: &str,
    tree: &KinematicTree,
) -> Result<CameraFileContents> {
    let file: CameraFile = parse_yaml(
        text,
        origin,
        "; a camera file has `cameras:` (name, link, pose, intrinsics, distortion, image, \
         estimate) and `targets:` (name, link, pose, board or marker, estimate); see \
         docs/file-formats.md",
    )?;
    let (length, angle) = match &file.units {
        None => (1.0, 1.0),
        Some(units) => (
            units
                .length
                .parse::<LengthUnit>()
                .map_err(|e| at(origin, "units.length", e))?
                .in_metres(),
            units
                .angle
                .parse::<AngleUnit>()
                .map_err(|e| at(origin, "units.angle", e))?
                .in_radians(),
        ),
    };
    let reader = Reader {
        origin,
        tree,
        length,
        angle,
    };
    let mut names = std::collections::HashSet::new();
    let mut cameras = Vec::new();
    for (k, entry) in file.cameras.iter().enumerate() {
        let place = format!("cameras[{k}] ({})", entry.name);
        if !names.insert(entry.name.clone()) {
            return Err(bad(origin, &place, "a second camera of this name".into()));
        }
        cameras.push(reader.camera(entry, &place)?);
    }
    if cameras.is_empty() {
        return Err(bad(origin, "cameras", "no camera is described".into()));
    }
    let mut targets = Vec::new();
    for (k, entry) in file.targets.iter().enumerate() {
        let place = format!("targets[{k}] ({})", entry.name);
        if !names.insert(entry.name.clone()) {
            return Err(bad(
                origin,
                &place,
                "a second camera or target of this name".into(),
            ));
        }
        targets.push(reader.target(entry, &place)?);
    }
    Ok(CameraFileContents { cameras, targets })
}

/// What every entry of one camera file is read with: the file, the robot and the file's units
/// (metres and radians per unit).
struct Reader<'a> {
    origin: &'a str,
    tree: &'a KinematicTree,
    length: f64,
    angle: f64,
}

impl Reader<'_> {
    /// An entry's pose, in metres and radians.
    fn pose(&self, entry: &PoseEntry, place: &str) -> Result<Pose> {
        let values = entry.xyz.iter().chain(entry.rpy.iter());
        if !values.clone().all(|v| v.is_finite() && v.abs() <= 1e4) {
            return Err(bad(
                self.origin,
                place,
                "the pose has a value that is not a finite number of at most 1e4".into(),
            ));
        }
        let [x, y, z] = entry.xyz.map(|v| v * self.length);
        let [r, p, w] = entry.rpy.map(|v| v * self.angle);
        Ok(Pose::from_parts(
            Translation3::new(x, y, z),
            rotation_from_rpy(r, p, w),
        ))
    }

    /// The link (or the world) an entry is mounted on.
    fn mount(&self, link: &str, place: &str) -> Result<Mount> {
        if link == "world" {
            return Ok(Mount::World);
        }
        self.tree.link_id(link).map(Mount::Link).map_err(|e| {
            bad(
                self.origin,
                place,
                format!("{e}; or `world` for one fixed in the world"),
            )
        })
    }

    /// One `cameras:` entry.
    fn camera(&self, entry: &CameraEntry, place: &str) -> Result<CameraSpec> {
        let intrinsics = Intrinsics {
            fx: entry.intrinsics.fx,
            fy: entry.intrinsics.fy,
            cx: entry.intrinsics.cx,
            cy: entry.intrinsics.cy,
            distortion: entry.distortion.unwrap_or([0.0; 5]),
            width: entry.image.width,
            height: entry.image.height,
        };
        if let Some(problem) = intrinsics.problem() {
            return Err(bad(self.origin, place, problem));
        }
        let estimate = entry.estimate.clone().unwrap_or(vec![Estimated::Pose]);
        Ok(CameraSpec {
            name: entry.name.clone(),
            mount: self.mount(&entry.link, place)?,
            mount_from_camera: self.pose(&entry.pose, place)?,
            intrinsics,
            estimate_pose: estimate.contains(&Estimated::Pose),
            estimate_intrinsics: estimate.contains(&Estimated::Intrinsics),
        })
    }

    /// One `targets:` entry.
    fn target(&self, entry: &TargetEntry, place: &str) -> Result<TargetSpec> {
        let shape = self.shape(entry, place)?;
        if entry
            .estimate
            .as_ref()
            .is_some_and(|e| e.contains(&Estimated::Intrinsics))
        {
            return Err(bad(
                self.origin,
                place,
                "a target has no intrinsics; estimate: [pose] or []".into(),
            ));
        }
        Ok(TargetSpec {
            name: entry.name.clone(),
            mount: self.mount(&entry.link, place)?,
            mount_from_target: self.pose(&entry.pose, place)?,
            shape,
            estimate_pose: entry
                .estimate
                .as_ref()
                .is_none_or(|e| e.contains(&Estimated::Pose)),
        })
    }

    /// A target's board (corners, spacing in metres) or marker.
    fn shape(&self, entry: &TargetEntry, place: &str) -> Result<TargetShape> {
        match (&entry.board, &entry.marker) {
            (Some(board), None) => {
                let spacing = board.spacing * self.length;
                if board.rows == 0 || board.columns == 0 || board.rows * board.columns > 100_000 {
                    return Err(bad(
                        self.origin,
                        place,
                        "a board needs 1 to 100000 corners".into(),
                    ));
                }
                if !(spacing.is_finite() && spacing > 0.0 && spacing <= 10.0) {
                    return Err(bad(
                        self.origin,
                        place,
                        "the board spacing must be positive (at most 10 m)".into(),
                    ));
                }
                Ok(TargetShape::Board {
                    rows: board.rows,
                    columns: board.columns,
                    spacing,
                })
            }
            (None, Some(_)) => Ok(TargetShape::Marker),
            _ => Err(bad(
                self.origin,
                place,
                "give either `board: {rows, columns, spacing}` or `marker: {}`".into(),
            )),
        }
    }
}

fn at(origin: &str, key: &str, error: Error) -> Error {
    match error {
        Error::InvalidData { message, .. } | Error::InvalidSetting { message, .. } => {
            bad(origin, key, message)
        }
        other => other,
    }
}

fn bad(origin: &str, place: &str, message: String) -> Error {
    Error::InvalidData {
        origin: format!("{origin}: {place}"),
        message,
    }
}

/// A camera file describing `cameras` and `targets` on `tree` (metres and radians), which
/// [`parse_camera_file`] reads back to the same values: what `simulate --observation camera`
/// hands a user, and the fitted cameras `calibrate --camera` writes for reuse.
pub fn camera_file_yaml(
    tree: &KinematicTree,
    cameras: &[CameraSpec],
    targets: &[TargetSpec],
) -> String {
    let mount = |mount: &Mount| match mount {
        Mount::World => "world".to_owned(),
        Mount::Link(link) => tree.link(*link).name.clone(),
    };
    let pose = |pose: &Pose| {
        let t = pose.translation.vector;
        let [r, p, y] = crate::math::rpy_from_rotation(&pose.rotation);
        format!(
            "{{xyz: [{:?}, {:?}, {:?}], rpy: [{r:?}, {p:?}, {y:?}]}}",
            t.x, t.y, t.z
        )
    };
    let mut text = String::from("units: {length: m, angle: rad}\ncameras:\n");
    for camera in cameras {
        let i = &camera.intrinsics;
        let [k1, k2, p1, p2, k3] = i.distortion;
        let mut estimate = Vec::new();
        if camera.estimate_pose {
            estimate.push("pose");
        }
        if camera.estimate_intrinsics {
            estimate.push("intrinsics");
        }
        text.push_str(&format!(
            "  - name: {}\n    link: {}\n    pose: {}\n    intrinsics: {{fx: {:?}, fy: {:?}, cx: \
             {:?}, cy: {:?}}}\n    distortion: [{k1:?}, {k2:?}, {p1:?}, {p2:?}, {k3:?}]\n    \
             image: {{width: {:?}, height: {:?}}}\n    estimate: [{}]\n",
            camera.name,
            mount(&camera.mount),
            pose(&camera.mount_from_camera),
            i.fx,
            i.fy,
            i.cx,
            i.cy,
            i.width,
            i.height,
            estimate.join(", ")
        ));
    }
    if !targets.is_empty() {
        text.push_str("targets:\n");
    }
    for target in targets {
        let shape = match &target.shape {
            TargetShape::Board {
                rows,
                columns,
                spacing,
            } => format!("board: {{rows: {rows}, columns: {columns}, spacing: {spacing:?}}}"),
            TargetShape::Marker => "marker: {}".to_owned(),
        };
        text.push_str(&format!(
            "  - name: {}\n    link: {}\n    pose: {}\n    {shape}\n    estimate: [{}]\n",
            target.name,
            mount(&target.mount),
            pose(&target.mount_from_target),
            if target.estimate_pose { "pose" } else { "" }
        ));
    }
    text
}
