//! Where a workflow's inputs come from: a file, text in memory, or the built-in Robonaut.

use super::Note;
use crate::io::{parse_stiffness, read_measured_tool_names, read_stiffness};
use crate::kinematics::{McpcModel, Stiffness};
use crate::tree::{detect_branches, Branches, KinematicTree};
use crate::urdf::{load_urdf, parse_urdf, UrdfImport};
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// The Robonaut generated from the paper's Table 1, built in so that every job works from any
/// directory.
pub const BUILT_IN_ROBONAUT: &str = include_str!("../../robots/robonaut/robonaut.urdf");

/// The built-in Robonaut's stiffness file (the paper's section 5.2 set-up).
pub const BUILT_IN_STIFFNESS: &str = include_str!("../../robots/robonaut/stiffness.yaml");

/// The robot: the built-in Robonaut, a URDF file, or URDF text (`origin` names it in messages).
#[derive(Debug, Clone, Default, PartialEq)]
pub enum RobotSource {
    /// The built-in Robonaut.
    #[default]
    BuiltIn,
    /// A URDF file.
    File(PathBuf),
    /// URDF text.
    Text {
        /// The URDF.
        text: String,
        /// What to call it in messages.
        origin: String,
    },
}

/// A stiffness file (docs/flexibility.md): the built-in Robonaut's, a file, or YAML text.
#[derive(Debug, Clone, PartialEq)]
pub enum StiffnessSource {
    /// The built-in Robonaut's stiffness file.
    BuiltIn,
    /// A YAML file.
    File(PathBuf),
    /// YAML text.
    Text {
        /// The YAML.
        text: String,
        /// What to call it in messages.
        origin: String,
    },
}

/// The calibration plan: chosen from the data's stage labels, staged, simultaneous, or a file.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum PlanSource {
    /// Staged when the rows are labelled torso / arms, else simultaneous.
    #[default]
    Auto,
    /// The paper's staging: the torso with the arms locked, then the arms.
    Staged,
    /// Every parameter from every measurement at once.
    Simultaneous,
    /// A plan file (YAML, docs/file-formats.md).
    File(PathBuf),
}

impl RobotSource {
    /// The URDF file, if the robot is one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            RobotSource::File(path) => Some(path),
            _ => None,
        }
    }

    /// Loads the robot; the loader's warnings go to `notes`.
    pub fn load(&self, notes: &mut Vec<Note>) -> Result<UrdfImport> {
        let import = match self {
            RobotSource::BuiltIn => parse_urdf(BUILT_IN_ROBONAUT, "built-in robonaut.urdf")?,
            RobotSource::File(path) => load_urdf(path)?,
            RobotSource::Text { text, origin } => parse_urdf(text, origin)?,
        };
        notes.extend(import.warnings.iter().map(Note::warning));
        Ok(import)
    }
}

impl StiffnessSource {
    /// Reads the stiffness of `tree`'s branches in `model`.
    pub fn read(&self, tree: &KinematicTree, model: &McpcModel) -> Result<Stiffness> {
        match self {
            StiffnessSource::BuiltIn => {
                parse_stiffness(BUILT_IN_STIFFNESS, "built-in stiffness.yaml", tree, model)
            }
            StiffnessSource::File(path) => read_stiffness(path, tree, model),
            StiffnessSource::Text { text, origin } => parse_stiffness(text, origin, tree, model),
        }
    }

    /// The file, if the stiffness is one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            StiffnessSource::File(path) => Some(path),
            _ => None,
        }
    }
}

/// Detects the branches, ending at the tool links named in `tools` if any.
pub fn branches(import: &UrdfImport, tools: Option<&[String]>) -> Result<Branches> {
    let tree = &import.tree;
    let tools = tools
        .map(|names| {
            names
                .iter()
                .map(|n| tree.link_id(n.trim()))
                .collect::<Result<Vec<_>>>()
        })
        .transpose()?;
    detect_branches(tree, tools.as_deref())
}

/// Detects the branches from the tools named, else from the links the measurement CSV's `tool`
/// column names (the measured tools), so that automatic detection cannot pick others.
pub fn measured_branches(
    import: &UrdfImport,
    tools: Option<&[String]>,
    measurements: &Path,
) -> Result<Branches> {
    if tools.is_some() {
        return branches(import, tools);
    }
    let measured = read_measured_tool_names(measurements)?;
    let tree = &import.tree;
    let ids = measured
        .iter()
        .map(|name| {
            tree.link_id(name).map_err(|e| Error::InvalidData {
                origin: format!("{}: tool column", measurements.display()),
                message: format!("{e}; the tool column names the measured tool links"),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    detect_branches(tree, Some(&ids))
}
