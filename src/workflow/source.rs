//! Where a workflow's inputs come from: files, text in memory, arrays, or the built-in
//! Robonaut; and loading them into the library's types.

use super::note::Note;
use crate::calibration::Plan;
use crate::error::{Error, Result};
use crate::io::{
    parse_stiffness, read_measured_targets, read_measured_tool_names, read_measurements, read_plan,
    read_stiffness, MeasurementReadOptions, MeasurementSet, MeasurementTable,
};
use crate::kinematics::{McpcModel, Stiffness};
use crate::tree::{detect_branches_from, Branches, KinematicTree, LinkId};
use crate::urdf::{parse_urdf, UrdfImport};
use std::path::{Path, PathBuf};

/// The Robonaut generated from the paper's Table 1, built in so that the main workflows run
/// without any file.
pub const BUILT_IN_ROBONAUT: &str = include_str!("../../robots/robonaut/robonaut.urdf");

/// How messages name the built-in Robonaut.
pub const BUILT_IN_ROBONAUT_ORIGIN: &str = "built-in robonaut.urdf";

/// The built-in Robonaut's stiffness file (the paper's section 5.2 set-up).
pub const BUILT_IN_STIFFNESS: &str = include_str!("../../robots/robonaut/stiffness.yaml");

/// How messages name the built-in stiffness file.
pub const BUILT_IN_STIFFNESS_ORIGIN: &str = "built-in robonaut stiffness.yaml";

/// A robot (URDF).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum RobotSource {
    /// The built-in Robonaut ([`BUILT_IN_ROBONAUT`]).
    #[default]
    BuiltIn,
    /// A URDF file.
    File(PathBuf),
    /// URDF text; `origin` names it in messages.
    Text {
        /// The URDF.
        text: String,
        /// E.g. `robot (string)`.
        origin: String,
    },
}

/// A robot as loaded: the tree with its loader warnings, and the URDF text it came from
/// (export rewrites that text).
#[derive(Debug, Clone)]
pub struct LoadedRobot {
    /// The kinematic tree and the loader's warnings.
    pub import: UrdfImport,
    /// The URDF text.
    pub text: String,
    /// How messages name the URDF.
    pub origin: String,
}

impl RobotSource {
    /// A file, or the built-in Robonaut when `None` (the CLI's `--robot`).
    pub fn from_path(path: Option<PathBuf>) -> Self {
        path.map_or(RobotSource::BuiltIn, RobotSource::File)
    }

    /// The file, if the robot is one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            RobotSource::File(path) => Some(path),
            _ => None,
        }
    }

    /// Reads and converts the URDF.
    pub fn load(&self) -> Result<LoadedRobot> {
        let (text, origin) = match self {
            RobotSource::BuiltIn => (
                BUILT_IN_ROBONAUT.to_owned(),
                BUILT_IN_ROBONAUT_ORIGIN.to_owned(),
            ),
            RobotSource::File(path) => (
                crate::limits::read_text(path, crate::limits::MAX_URDF_BYTES)?,
                path.display().to_string(),
            ),
            RobotSource::Text { text, origin } => (text.clone(), origin.clone()),
        };
        let import = parse_urdf(&text, &origin)?;
        Ok(LoadedRobot {
            import,
            text,
            origin,
        })
    }
}

impl LoadedRobot {
    /// The kinematic tree.
    pub fn tree(&self) -> &KinematicTree {
        &self.import.tree
    }

    /// The loader's warnings as notes.
    pub fn notes(&self) -> Vec<Note> {
        self.import.warnings.iter().map(Note::warning).collect()
    }
}

/// A robot with its branches and nominal MCPC model: the first steps of `simulate` and `plan`.
pub(crate) struct NominalRobot {
    /// The kinematic tree and the loader's warnings.
    pub import: UrdfImport,
    /// The tools, the coupled branch and the reference link.
    pub branches: Branches,
    /// The nominal model of `branches`.
    pub model: McpcModel,
}

impl RobotSource {
    /// Loads the robot, adds its loader warnings to `notes` and builds the nominal model of
    /// `tools` measured from `reference` ([`branches`]).
    pub(crate) fn nominal(
        &self,
        tools: Option<&[String]>,
        reference: Option<&str>,
        notes: &mut Vec<Note>,
    ) -> Result<NominalRobot> {
        let robot = self.load()?;
        notes.extend(robot.notes());
        let import = robot.import;
        let branches = branches(&import, tools, reference)?;
        let model = McpcModel::from_tree(&import.tree, &branches)?;
        Ok(NominalRobot {
            import,
            branches,
            model,
        })
    }
}

/// The link fixed in the world while measuring: `name`, or the root without one. An unknown
/// name is an error that lists the links there are.
pub fn reference_link(tree: &KinematicTree, name: Option<&str>) -> Result<LinkId> {
    let Some(name) = name.map(str::trim) else {
        return Ok(tree.root());
    };
    tree.link_id(name).map_err(|_| {
        Error::Branches(format!(
            "reference link '{name}' is not a link of robot '{}'; its links are: {}",
            tree.name(),
            tree.links()
                .iter()
                .map(|l| l.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ))
    })
}

/// Detects branches from the named tools (else automatically), measured from the reference
/// link (else the root).
pub fn branches(
    import: &UrdfImport,
    tools: Option<&[String]>,
    reference: Option<&str>,
) -> Result<Branches> {
    let tree = &import.tree;
    let tools = tools
        .map(|names| {
            names
                .iter()
                .map(|n| tree.link_id(n.trim()))
                .collect::<Result<Vec<_>>>()
        })
        .transpose()?;
    detect_branches_from(tree, tools.as_deref(), reference_link(tree, reference)?)
}

/// Detects branches from the tools the user named, else from the links the measurements'
/// `tool` column names (the measured tools), so that automatic detection cannot pick others;
/// measured from the reference link (else the root).
pub fn measured_branches(
    import: &UrdfImport,
    tools: Option<&[String]>,
    reference: Option<&str>,
    measurements: &MeasurementSource,
) -> Result<Branches> {
    measured_branches_of(import, tools, reference, measurements, || {
        measurements.tool_names()
    })
}

/// As [`measured_branches`], the measured tool links given by `measured` (called only when
/// `tools` is `None`).
pub(crate) fn measured_branches_of(
    import: &UrdfImport,
    tools: Option<&[String]>,
    reference: Option<&str>,
    measurements: &MeasurementSource,
    measured: impl FnOnce() -> Result<Vec<String>>,
) -> Result<Branches> {
    if tools.is_some() {
        return branches(import, tools, reference);
    }
    let measured = measured()?;
    let tree = &import.tree;
    let ids = measured
        .iter()
        .map(|name| {
            tree.link_id(name).map_err(|e| Error::InvalidData {
                origin: match measurements {
                    MeasurementSource::Csv(path) => format!("{}: tool column", path.display()),
                    MeasurementSource::Files(paths) => format!(
                        "{}: tool column",
                        super::measurement_files::origin(paths)
                    ),
                    MeasurementSource::Table(table) => table.place_of_tool(name),
                },
                message: format!(
                    "{e} of robot '{}'; the tool column names the measured tool links of the robot loaded (points on one body: name the body's link with `tools`; measurements of another robot: give its URDF with `robot`)",
                    tree.name()
                ),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    detect_branches_from(tree, Some(&ids), reference_link(tree, reference)?)
}

/// The measured points the robot's URDF lacks, added to its tree as marker links (a fixed
/// leaf link each, at its parent link's origin, whose offset is calibrated as a tool).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MeasuredPoints {
    /// `(marker link, parent link)` of every link added, in order of first appearance.
    pub added: Vec<(String, String)>,
    /// The tools of the model when points were added: the `--tools` with each body whose
    /// points are measured replaced by its marker links, else the measured links. `None`: no
    /// points added, the tools are chosen as before.
    pub tools: Option<Vec<String>>,
}

impl MeasuredPoints {
    /// The note naming the added marker links, if any.
    pub fn note(&self) -> Option<Note> {
        if self.added.is_empty() {
            return None;
        }
        let listed: Vec<String> = self
            .added
            .iter()
            .map(|(link, parent)| format!("'{link}' on '{parent}'"))
            .collect();
        Some(Note::info(format!(
            "{} measured point(s) read as marker links, each a tool with its own calibrated offset on its link: {}; calibrated.urdf gets these links, params.yaml lists them",
            listed.len(),
            listed.join(", ")
        )))
    }
}

/// Adds the points the measurements name (a `point` column: link `<tool>_<point>`; or, when
/// `--tools` names one link and no `tool` value is a link of the robot, every `tool` value a
/// point on that link) to `import`'s tree as marker links. A link of that name that is already
/// a fixed leaf below the tool (a markers URDF, or a previous export) is used as it is.
pub fn add_measured_points(
    import: &mut UrdfImport,
    tools: Option<&[String]>,
    measurements: &MeasurementSource,
) -> Result<MeasuredPoints> {
    add_measured_points_of(import, tools, measurements, measurements.targets()?)
}

/// As [`add_measured_points`], with the measurements' `(tool, point)` pairs read already
/// ([`MeasurementSource::targets`]).
pub(crate) fn add_measured_points_of(
    import: &mut UrdfImport,
    tools: Option<&[String]>,
    measurements: &MeasurementSource,
    pairs: Vec<(Option<String>, Option<String>)>,
) -> Result<MeasuredPoints> {
    let tree = &mut import.tree;
    let body = tools
        .filter(|t| t.len() == 1)
        .map(|t| t[0].trim().to_owned());
    let any_link = pairs.iter().any(|(tool, point)| {
        point.is_none() && tool.as_ref().is_some_and(|t| tree.link_id(t).is_ok())
    });
    let origin = measurements.origin();
    let mut points = MeasuredPoints::default();
    let mut measured: Vec<String> = Vec::new();
    for (tool, point) in pairs {
        let Some(tool) = tool.or_else(|| body.clone()) else {
            return Err(Error::InvalidData {
                origin,
                message: "the measurements have no 'tool' column; add one naming the measured tool link of each row, or name the one measured tool (the body the points are on) with `tools`".into(),
            });
        };
        let (name, parent) = match (&point, &body) {
            (Some(point), _) => (
                crate::io::measured_link_name(&tool, Some(point)),
                tool.clone(),
            ),
            (None, Some(body)) if !any_link && tree.link_id(&tool).is_err() => {
                (tool.clone(), body.clone())
            }
            (None, _) => {
                measured.push(tool);
                continue;
            }
        };
        let parent_id = tree.link_id(&parent).map_err(|e| Error::InvalidData {
            origin: origin.clone(),
            message: format!("{e}; the points of the measurements are on link '{parent}'"),
        })?;
        match tree.link_id(&name) {
            Ok(existing) => {
                let link = tree.link(existing);
                let fixed_leaf = link.child_joints.is_empty()
                    && link.parent_joint.is_some_and(|j| {
                        let joint = tree.joint(j);
                        joint.parent == parent_id && !joint.kind.is_movable()
                    });
                if !fixed_leaf {
                    return Err(Error::InvalidData {
                        origin: origin.clone(),
                        message: format!(
                            "the measured point '{name}' would be a marker link on '{parent}', but the robot has a link '{name}' that is not a fixed leaf link below '{parent}'; rename the point"
                        ),
                    });
                }
            }
            Err(_) => {
                tree.add_marker_link(&name, parent_id)?;
                points.added.push((name.clone(), parent.clone()));
            }
        }
        measured.push(name);
    }
    if points.added.is_empty() {
        return Ok(points);
    }
    let parent_of = |link: &str| points.added.iter().find(|(l, _)| l == link).map(|(_, p)| p);
    points.tools = Some(match tools {
        Some(tools) => {
            let mut chosen: Vec<String> = Vec::new();
            for tool in tools.iter().map(|t| t.trim()) {
                let markers = measured
                    .iter()
                    .filter(|m| parent_of(m).is_some_and(|p| p == tool));
                let mut markers = markers.cloned().peekable();
                if markers.peek().is_none() || measured.iter().any(|m| m == tool) {
                    chosen.push(tool.to_owned());
                }
                chosen.extend(markers);
            }
            chosen
        }
        None => measured,
    });
    Ok(points)
}

/// Measurements: a CSV file (docs/file-formats.md) or arrays.
// One value per workflow configuration, never in a collection: boxing the table would only
// add an indirection to every constructor.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum MeasurementSource {
    /// A measurement CSV.
    Csv(PathBuf),
    /// Several measurement CSVs read as one set, in order, each file its own session (rows
    /// without a `session` get the file's name: `super::measurement_files`); at least two
    /// ([`MeasurementSource::from_paths`]).
    Files(Vec<PathBuf>),
    /// Arrays in memory.
    Table(MeasurementTable),
}

impl Default for MeasurementSource {
    /// An empty path: reading it fails with a message naming the missing file.
    fn default() -> Self {
        MeasurementSource::Csv(PathBuf::new())
    }
}

impl MeasurementSource {
    /// The measurement files given: none is the default (an error naming the missing file
    /// when read), one a [`MeasurementSource::Csv`], more [`MeasurementSource::Files`].
    pub fn from_paths(mut paths: Vec<PathBuf>) -> Self {
        match paths.len() {
            0 => Self::default(),
            1 => MeasurementSource::Csv(paths.remove(0)),
            _ => MeasurementSource::Files(paths),
        }
    }

    /// How messages and reports name the measurements: the path, or the table's origin.
    pub fn origin(&self) -> String {
        match self {
            MeasurementSource::Csv(path) => path.display().to_string(),
            MeasurementSource::Files(paths) => super::measurement_files::origin(paths),
            MeasurementSource::Table(table) => table.origin.clone(),
        }
    }

    /// The files the measurements are read from (none for a table).
    pub fn paths(&self) -> Vec<&Path> {
        match self {
            MeasurementSource::Csv(path) => vec![path.as_path()],
            MeasurementSource::Files(paths) => paths.iter().map(PathBuf::as_path).collect(),
            MeasurementSource::Table(_) => Vec::new(),
        }
    }

    /// The distinct `(tool, point)` pairs the rows name, in order of first appearance
    /// ([`crate::io::measured_targets`]).
    pub fn targets(&self) -> Result<Vec<(Option<String>, Option<String>)>> {
        match self {
            MeasurementSource::Csv(path) => read_measured_targets(path),
            MeasurementSource::Files(paths) => Ok(super::measurement_files::union_in_order(
                paths
                    .iter()
                    .map(|p| read_measured_targets(p))
                    .collect::<Result<_>>()?,
            )),
            MeasurementSource::Table(table) => table.targets(),
        }
    }

    /// The distinct measured tool links, in order of first appearance, from the `targets`
    /// read already where they tell (a file whose rows all name a tool: the tools of its
    /// pairs in order), else read ([`Self::tool_names`]). One scan of a large file, not two.
    pub fn tool_names_given(
        &self,
        targets: &[(Option<String>, Option<String>)],
    ) -> Result<Vec<String>> {
        let every_row_names_a_tool = !targets.is_empty() && targets.iter().all(|t| t.0.is_some());
        if !(matches!(self, MeasurementSource::Csv(_)) && every_row_names_a_tool) {
            return self.tool_names();
        }
        let mut names: Vec<String> = Vec::new();
        for tool in targets.iter().filter_map(|t| t.0.as_ref()) {
            if !names.contains(tool) {
                names.push(tool.clone());
            }
        }
        Ok(names)
    }

    /// The distinct measured tool links, in order of first appearance.
    pub fn tool_names(&self) -> Result<Vec<String>> {
        match self {
            MeasurementSource::Csv(path) => read_measured_tool_names(path),
            MeasurementSource::Files(paths) => Ok(super::measurement_files::union_in_order(
                paths
                    .iter()
                    .map(|p| read_measured_tool_names(p))
                    .collect::<Result<_>>()?,
            )),
            MeasurementSource::Table(table) => table.tool_names(),
        }
    }

    /// The measurements for the robot `tree` with model `model`.
    pub fn read(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        options: &MeasurementReadOptions,
    ) -> Result<MeasurementSet> {
        match self {
            MeasurementSource::Csv(path) => read_measurements(path, tree, model, options),
            MeasurementSource::Files(paths) => {
                super::measurement_files::read_files(paths, tree, model, options)
            }
            MeasurementSource::Table(table) => table.to_measurements(tree, model, options),
        }
    }
}

/// A stiffness file (docs/flexibility.md): link stiffness, joint compliance, payloads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StiffnessSource {
    /// The built-in Robonaut's ([`BUILT_IN_STIFFNESS`]).
    BuiltIn,
    /// A YAML file.
    File(PathBuf),
    /// YAML text; `origin` names it in messages.
    Text {
        /// The YAML.
        text: String,
        /// E.g. `stiffness (string)`.
        origin: String,
    },
}

impl StiffnessSource {
    /// How messages and reports name the stiffness.
    pub fn origin(&self) -> String {
        match self {
            StiffnessSource::BuiltIn => BUILT_IN_STIFFNESS_ORIGIN.to_owned(),
            StiffnessSource::File(path) => path.display().to_string(),
            StiffnessSource::Text { origin, .. } => origin.clone(),
        }
    }

    /// The file, if the stiffness is one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            StiffnessSource::File(path) => Some(path),
            _ => None,
        }
    }

    /// Reads the stiffness for the robot `tree` with model `model` (names are checked).
    pub fn read(&self, tree: &KinematicTree, model: &McpcModel) -> Result<Stiffness> {
        match self {
            StiffnessSource::BuiltIn => {
                parse_stiffness(BUILT_IN_STIFFNESS, BUILT_IN_STIFFNESS_ORIGIN, tree, model)
            }
            StiffnessSource::File(path) => read_stiffness(path, tree, model),
            StiffnessSource::Text { text, origin } => parse_stiffness(text, origin, tree, model),
        }
    }
}

/// A calibration plan.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum PlanSource {
    /// Staged when rows are labelled `stage` = torso, else simultaneous (with a note).
    #[default]
    Auto,
    /// The paper's staging: the torso with the arms locked, then the arms.
    Staged,
    /// Every parameter from every measurement at once.
    Simultaneous,
    /// A plan file (YAML, docs/file-formats.md).
    File(PathBuf),
}

impl PlanSource {
    /// The file, if the plan is one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            PlanSource::File(path) => Some(path),
            _ => None,
        }
    }

    /// The plan, its name for the report, and for [`PlanSource::Auto`] without torso rows
    /// (`labelled` false) the note saying why the simultaneous plan is used.
    pub fn resolve(&self, labelled: bool) -> Result<(Plan, String, Option<Note>)> {
        Ok(match self {
            PlanSource::Staged => (Plan::staged(), "staged".into(), None),
            PlanSource::Simultaneous => (Plan::simultaneous(), "simultaneous".into(), None),
            PlanSource::File(path) => (
                read_plan(path)?,
                format!("plan file {}", path.display()),
                None,
            ),
            PlanSource::Auto if labelled => (Plan::staged(), "staged".into(), None),
            PlanSource::Auto => (
                Plan::simultaneous(),
                "simultaneous".into(),
                Some(Note::info(
                    "no rows are labelled stage=torso, so the simultaneous plan is used (label torso rows, taken with the arms locked, for the staged plan)",
                )),
            ),
        })
    }
}
