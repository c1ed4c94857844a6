//! `calibrate --contacts C.csv --contact-setup S.yaml` (issue 29): a robot calibrated from
//! its contacts alone — flush faces and contact points on a plane per session, touches, a bar.
//!
//! 1. The tools of the setup file, measured from the reference link (a sole), make one model
//!    for all chains; each row becomes a contact measurement with its nuisance blocks (a plane
//!    per session, a face or contact point per tool, the bar).
//! 2. Each plane starts from a closed-form fit to the nominal robot's contacts (the mean face
//!    normal or the points' least-squares plane, through their centroid), so that nominal
//!    planes far off (0.3 m) converge.
//! 3. "Before": the registered nominal robot — only the nuisance fitted, same least squares.
//!    "After": the joint frames and the nuisance from there.
//! 4. Held-out contacts (`--validation`, else every fifth row) scored with the training
//!    session's plane (primary) and with a plane refitted to them (diagnostic).

use super::camera_tracker::CameraTrackerInput;
use super::contact_cv::{
    candidate_problem, choose_contact_model, fit_candidate, model_markdown, ContactCvInput,
    ContactFolds,
};
use super::contact_fit::{plane_start, ContactProblem};
use super::contact_model::{only_tools, robot_free, setup_model, written_differs};
use super::contact_model::{written_scores, SetupModel};
use super::contact_scale::{hold_scale, Fitted, ScaleCheck};
use super::contact_tracker::{contact_kind_scales, tracker_links, ContactTracker};
use super::model_choice::{ModelChoice, ParameterPatterns};
use super::note::Note;
use super::source::RobotSource;
use crate::calibration::NuisanceBlock;
use crate::calibration::{IdentificationOptions, Nuisance};
use crate::error::{Error, Result};
use crate::io::{read_contact_setup, ContactSetup};
use crate::io::{read_contacts, ContactKind, ContactRow, ContactTable};
use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::measurement::{Contact, ContactFace, ContactPlane, Measurement, Observation};
use crate::report::{contact_report, kinds_markdown, written_contacts, ContactScores};
use crate::sim::contact_free_parameters;
use crate::tree::KinematicTree;
use crate::urdf::{export_urdf_with, ExportOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What `calibrate --contacts` reads.
#[derive(Debug, Clone, Default)]
pub struct ContactCalibrateConfig {
    /// The robot.
    pub robot: RobotSource,
    /// The contacts CSV (training rows).
    pub contacts: PathBuf,
    /// The setup YAML.
    pub setup: PathBuf,
    /// Held-out contacts (same format) [default: every fifth row of `contacts`].
    pub validation: Option<PathBuf>,
    /// The reference link; overrides the setup's.
    pub reference_link: Option<String>,
    /// The setup's tools (by setup name or link) to calibrate, e.g. one side of a two-handed
    /// set-up; contacts of other tools are left out, and so are their chains [default: all].
    pub tools: Option<Vec<String>>,
    /// Tracker rows fitted with the contacts, each with its σ (`measurements`).
    pub tracker: Option<CameraTrackerInput>,
    /// Which model describes the robot: joint zero offsets, every joint frame's four
    /// parameters, chosen by cross-validation (`auto`), or (`Adaptive`, the default) the full
    /// geometry unless its fit leaves residuals over [`super::CONTACT_ADAPTIVE_SIGMA`] times the
    /// declared σ's, then as `auto` (`docs/contacts.md`, "The model the data support").
    pub model: ModelChoice,
    /// The default prior on the nominal values with its σ's times this factor (`prior`,
    /// `prior_scale`); `None`: no prior (`auto` still offers the full geometry with it).
    pub prior: Option<f64>,
    /// Cross-validate over this many folds (`cv`; a table in the report) [`auto`: 5].
    pub cv: Option<usize>,
    /// Fold assignments of the cross-validation (seeds `seed`, `seed + 1`, …) [0: 3].
    pub cv_repeats: usize,
    /// The seed of the fold assignments.
    pub seed: u64,
    /// Parameters frozen or freed by name (`freeze`, `free`; see params.yaml's names).
    pub patterns: ParameterPatterns,
}

/// The outputs of `calibrate --contacts`.
#[derive(Debug, Clone)]
pub struct ContactCalibration {
    /// Loader warnings and what the user should know.
    pub notes: Vec<Note>,
    /// report.md.
    pub report_markdown: String,
    /// report.json.
    pub report_json: serde_json::Value,
    /// calibrated.urdf (all chains), `None` when the verdict failed.
    pub urdf: Option<String>,
    /// Why the verdict failed when the calibrated robot beat the registered nominal robot but
    /// cannot be trusted (its size off: `docs/contacts.md`, "The length scale").
    pub refused: Option<String>,
}

/// The files `calibrate --contacts` writes into its output folder.
pub const CONTACT_OUTPUTS: [&str; 3] = ["report.md", "report.json", "calibrated.urdf"];

impl ContactCalibration {
    /// Whether the calibrated robot beat the registered nominal robot (calibrated.urdf
    /// written).
    pub fn usable(&self) -> bool {
        self.urdf.is_some()
    }

    /// Writes the outputs as the whole contents of `out`.
    pub fn write(&self, out: &Path) -> Result<()> {
        let mut files = vec![
            (
                "report.md".to_owned(),
                self.report_markdown.clone().into_bytes(),
            ),
            (
                "report.json".to_owned(),
                serde_json::to_vec_pretty(&self.report_json).map_err(|e| Error::InvalidData {
                    origin: "report.json".into(),
                    message: e.to_string(),
                })?,
            ),
        ];
        if let Some(urdf) = &self.urdf {
            files.push(("calibrated.urdf".to_owned(), urdf.clone().into_bytes()));
        }
        crate::io::replace_folder(out, &files)
    }
}

/// Calibrates from contacts (see the module's documentation).
pub fn calibrate_contacts(config: &ContactCalibrateConfig) -> Result<ContactCalibration> {
    let robot = config.robot.load()?;
    let mut notes = robot.notes();
    let mut setup = read_contact_setup(&config.setup)?;
    let tree = &robot.import.tree;
    let (mut training, mut validation) = read_rows(config, tree, &mut notes)?;
    if let Some(wanted) = &config.tools {
        let rows = (&mut training, &mut validation);
        notes.push(only_tools(&mut setup, wanted, rows, &config.setup)?);
    }
    let tracked = match &config.tracker {
        Some(input) => tracker_links(input)?,
        None => Vec::new(),
    };
    let SetupModel {
        links,
        reference,
        model,
    } = setup_model(
        &robot.import,
        (&setup, &config.setup),
        config.reference_link.as_ref(),
        &tracked,
    )?;
    let (model, tracker) = match &config.tracker {
        Some(input) => {
            let (model, tracker) = ContactTracker::read(input, tree, model)?;
            notes.extend(tracker.check_setup(&setup, &config.setup, tree, &model)?);
            (model, Some(tracker))
        }
        None => (model, None),
    };
    let origin = config.contacts.display().to_string();
    let mut problem = contact_problem(tree, model, &setup, &training, &validation, &origin)?;
    problem.robot_free = robot_free(tree, &problem.model, false, &config.patterns)?;
    let mut options = contact_options(&setup);
    if let (Some(tracker), Some(input)) = (&tracker, &config.tracker) {
        problem.training.extend(tracker.rows.iter().cloned());
        problem.registration_free = tracker.free.clone();
        options.position_sigma = input.position_sigma;
        options.rotation_sigma = input.rotation_sigma;
        notes.push(Note::info(format!(
            "{} tracker rows fitted with the contacts (each row kind by its σ); they are not \
             held out: the verdict scores the held-out contacts",
            tracker.rows.len()
        )));
    }
    let (fitted, scale) = fit_holding_scale(config, tree, &problem, &options, &mut notes)?;
    let refused = scale.refused;
    let (problem, fit, spec, cv) = fitted;
    let scores = ContactScores::new(&problem, &fit, &options)?;
    let mut calibrated = problem.model.clone();
    calibrated.set_parameters(&fit.after.parameters)?;
    let kinds = contact_kind_scales(&problem, &fit, &options)?;
    let registration = tracker.as_ref().map(|t| t.registration(&calibrated));
    let better = scores.better_than_nominal() && refused.is_none();
    let export = if better {
        let export_options = ExportOptions {
            add_tool_links: true,
            ..ExportOptions::default()
        };
        // Joint zero offsets (`model` offsets) go into the URDF as turned child frames.
        Some(export_urdf_with(
            &robot.text,
            &robot.origin,
            tree,
            &calibrated.with_offsets_absorbed(),
            &export_options,
        )?)
    } else {
        None
    };
    let (mut report_markdown, mut report_json) = contact_report(
        tree,
        &problem,
        &fit,
        &scores,
        reference
            .as_deref()
            .unwrap_or(tree.link(tree.root()).name.as_str()),
        export.as_ref().map(|e| e.changes.len()),
        refused.as_deref(),
    );
    report_markdown.push_str(&kinds_markdown(&kinds, registration.as_ref()));
    report_markdown.push_str(&model_markdown(spec, cv.as_ref()));
    if let Some(object) = report_json.as_object_mut() {
        object.insert("kinds".into(), serde_json::json!(kinds));
        object.insert("tracker".into(), serde_json::json!(registration));
        object.insert(
            "model".into(),
            serde_json::json!({ "name": spec.name(), "offsets": spec.offsets, "prior": spec.prior }),
        );
        object.insert("model_choice".into(), serde_json::json!(cv));
        object.insert("size_ratio".into(), serde_json::json!(scale.ratio));
        object.insert("refused".into(), serde_json::json!(refused));
    }
    if let Some(export) = &export {
        let placed = (&problem, &calibrated, &fit);
        let written = written_scores(&export.urdf, &links, reference.as_deref(), placed, &options)?;
        let (markdown, json) = written_contacts(&written, scores.judged().1);
        report_markdown.push_str(&markdown);
        if let Some(object) = report_json.as_object_mut() {
            object.insert("written".into(), json);
        }
        notes.extend(written_differs(&written, &scores));
    }
    Ok(ContactCalibration {
        notes,
        report_markdown,
        report_json,
        urdf: export.map(|e| e.urdf),
        refused,
    })
}

/// [`fit_model`], then [`hold_scale`]: refitted with the prior when the model was the data's
/// choice and the fit changed the robot's size; the kept fit's size, and the reason the
/// verdict fails when it is still off.
fn fit_holding_scale(
    config: &ContactCalibrateConfig,
    tree: &KinematicTree,
    problem: &ContactProblem,
    options: &IdentificationOptions,
    notes: &mut Vec<Note>,
) -> Result<(Fitted, ScaleCheck)> {
    let fitted = fit_model(config, tree, problem, options, notes)?;
    let refit = |model, prior, notes: &mut Vec<Note>| {
        let config = ContactCalibrateConfig {
            model,
            prior,
            cv: None,
            ..config.clone()
        };
        fit_model(&config, tree, problem, options, notes)
    };
    hold_scale((config.model, config.prior), problem, fitted, refit, notes)
}

/// The model the config asks for or the data choose ([`choose_contact_model`]), as a problem,
/// and its fit.
fn fit_model(
    config: &ContactCalibrateConfig,
    tree: &KinematicTree,
    problem: &ContactProblem,
    options: &IdentificationOptions,
    notes: &mut Vec<Note>,
) -> Result<Fitted> {
    let input = ContactCvInput {
        tree,
        base: problem,
        patterns: &config.patterns,
        options,
        prior_scale: config.prior.unwrap_or(1.0),
    };
    let folds = ContactFolds {
        k: config.cv,
        repeats: config.cv_repeats,
        seed: config.seed,
    };
    let prior = config.prior.is_some();
    let choice = choose_contact_model(&input, config.model, prior, folds, notes)?;
    let problem = candidate_problem(tree, problem, choice.spec, &config.patterns)?;
    let fit = match choice.fit {
        Some(fit) => fit,
        None => fit_candidate(&problem, options, choice.spec, input.prior_scale)?,
    };
    Ok((problem, fit, choice.spec, choice.cv))
}

/// The training and held-out contacts: the contacts file and the validation file, or every
/// fifth row of the contacts file held out (said in a note).
fn read_rows(
    config: &ContactCalibrateConfig,
    tree: &KinematicTree,
    notes: &mut Vec<Note>,
) -> Result<(Vec<ContactRow>, Vec<ContactRow>)> {
    let training = read_contacts(&config.contacts, tree)?;
    notes.extend(table_notes(&training, &config.contacts));
    if let Some(path) = &config.validation {
        let table = read_contacts(path, tree)?;
        notes.extend(table_notes(&table, path));
        return Ok((training.rows, table.rows));
    }
    notes.push(Note::info(
        "no `validation` file: every fifth row is held out",
    ));
    let (train, held): (Vec<_>, Vec<_>) = training
        .rows
        .into_iter()
        .enumerate()
        .partition(|(k, _)| k % 5 != 4);
    Ok((
        train.into_iter().map(|(_, r)| r).collect(),
        held.into_iter().map(|(_, r)| r).collect(),
    ))
}

fn table_notes(table: &ContactTable, path: &Path) -> Vec<Note> {
    let mut notes = Vec::new();
    if !table.ignored_columns.is_empty() {
        notes.push(Note::warning(format!(
            "{}: columns that are no joint of the robot are ignored: {}",
            path.display(),
            table.ignored_columns.join(", ")
        )));
    }
    notes
}

/// The identification options of a contact fit: the setup's σ's.
pub fn contact_options(setup: &ContactSetup) -> IdentificationOptions {
    IdentificationOptions {
        max_iterations: 200,
        height_sigma: setup.sigma.height,
        tilt_sigma: setup.sigma.tilt,
        gap_sigma: setup.sigma.gap,
        length_sigma: setup.sigma.length,
        ..IdentificationOptions::default()
    }
}

/// Builds the contact problem of `training` and `validation` rows on `model` (`origin` names
/// the contacts file in messages).
pub fn contact_problem(
    tree: &KinematicTree,
    model: McpcModel,
    setup: &ContactSetup,
    training: &[ContactRow],
    validation: &[ContactRow],
    origin: &str,
) -> Result<ContactProblem> {
    let mut builder = Builder {
        setup,
        origin,
        world: model.world_from_base(),
        nuisance: Nuisance::default(),
        free: Vec::new(),
        planes: BTreeMap::new(),
        faces: BTreeMap::new(),
        points: BTreeMap::new(),
        bar: None,
    };
    let tool_index = tool_indices(tree, &model, setup)?;
    let mut kinds = Vec::new();
    let mut measurements = [Vec::new(), Vec::new()];
    for (set, rows) in [training, validation].iter().enumerate() {
        for row in rows.iter() {
            let (tool, contact) = builder.contact(row, &tool_index)?;
            if !kinds.contains(&row.kind) {
                kinds.push(row.kind);
            }
            measurements[set].push(Measurement {
                tool,
                q: row.q.clone(),
                observation: Observation::Contact(Box::new(contact)),
                stage: None,
                payload: None,
                session: Some(row.session.clone()),
            });
        }
    }
    let [mut training, mut validation] = measurements;
    let setup_planes = builder
        .planes
        .iter()
        .map(|(s, (_, pose))| (s.clone(), *pose))
        .collect();
    // Each plane starts from a closed-form fit to the nominal robot's training contacts.
    for (session, (block, nominal)) in &builder.planes {
        let rows: Vec<&Measurement> = training
            .iter()
            .filter(|m| m.session.as_deref() == Some(session))
            .collect();
        let start = plane_start(&model, &builder.nuisance, &rows, nominal);
        for m in training.iter_mut().chain(validation.iter_mut()) {
            set_plane_nominal(m, *block, start);
        }
    }
    if !setup.free.face_offset {
        builder
            .free
            .extend(relative_face_offsets(&builder.nuisance, &training));
        builder.free.sort_unstable();
        builder.free.dedup();
    }
    let planes = builder
        .planes
        .iter()
        .map(|(s, (b, _))| (s.clone(), *b))
        .collect();
    Ok(ContactProblem {
        robot_free: contact_free_parameters(&model),
        model,
        nuisance: builder.nuisance,
        free_nuisance: builder.free,
        training,
        validation,
        planes,
        setup_planes,
        kinds,
        registration_free: Vec::new(),
    })
}

/// The face offsets a flush fit can determine (indices among the nuisance values): a plane's
/// height aliases a face's offset along its normal, but where several tools press on the same
/// planes only one offset per group of tools linked by shared planes is aliased. The first
/// tool's (lowest face block) of each group stays held; the others' offsets, relative to it,
/// are freed.
fn relative_face_offsets(nuisance: &Nuisance, rows: &[Measurement]) -> Vec<usize> {
    // Union–find over face blocks, joined through the planes they share.
    let mut parent: BTreeMap<usize, usize> = BTreeMap::new();
    let mut plane_face: BTreeMap<usize, usize> = BTreeMap::new();
    fn root(parent: &BTreeMap<usize, usize>, mut k: usize) -> usize {
        while let Some(&p) = parent.get(&k).filter(|&&p| p != k) {
            k = p;
        }
        k
    }
    for m in rows {
        let Some(&Contact::Flush { plane, face }) = m.observation.contact() else {
            continue;
        };
        parent.entry(face.block).or_insert(face.block);
        let other = *plane_face.entry(plane.block).or_insert(face.block);
        let (a, b) = (root(&parent, face.block), root(&parent, other));
        if a != b {
            parent.insert(a.max(b), a.min(b));
        }
    }
    parent
        .keys()
        .filter(|&&face| root(&parent, face) != face)
        .map(|&face| nuisance.offset(face))
        .collect()
}

/// Each setup tool's index among the model's tools.
fn tool_indices(
    tree: &KinematicTree,
    model: &McpcModel,
    setup: &ContactSetup,
) -> Result<BTreeMap<String, usize>> {
    setup
        .tools
        .iter()
        .map(|(name, tool)| {
            let link = tree.link_id(tool.link.trim())?;
            let index = model
                .tools()
                .iter()
                .position(|t| t.link == link)
                .ok_or_else(|| Error::InvalidData {
                    origin: "contact setup".into(),
                    message: format!(
                        "tool '{name}': link '{}' is not a tool of the model",
                        tool.link
                    ),
                })?;
            Ok((name.clone(), index))
        })
        .collect()
}

fn set_plane_nominal(m: &mut Measurement, block: usize, pose: Pose) {
    if let Some(Contact::Flush { plane, .. } | Contact::Point { plane, .. }) =
        m.observation.contact_mut()
    {
        if plane.block == block {
            plane.nominal = pose;
        }
    }
}

/// Nuisance blocks made as rows need them.
struct Builder<'a> {
    setup: &'a ContactSetup,
    origin: &'a str,
    /// The reference link in the measurement frame (the setup's planes are in the reference
    /// link; identity unless tracker rows register the model to their frame).
    world: Pose,
    nuisance: Nuisance,
    free: Vec<usize>,
    /// Session → (block, the setup's nominal plane).
    planes: BTreeMap<String, (usize, Pose)>,
    /// Tool → (block, nominal face).
    faces: BTreeMap<String, (usize, Pose)>,
    /// Tool → block.
    points: BTreeMap<String, usize>,
    bar: Option<usize>,
}

impl Builder<'_> {
    fn add(&mut self, name: String, names: &[&str], values: Vec<f64>, free: &[bool]) -> usize {
        let start = self.nuisance.len();
        self.free
            .extend((0..values.len()).filter(|&k| free[k]).map(|k| start + k));
        self.nuisance.blocks.push(NuisanceBlock {
            name,
            parameter_names: names.iter().map(|s| s.to_string()).collect(),
            values,
        });
        self.nuisance.blocks.len() - 1
    }

    fn fail(&self, row: &ContactRow, message: String) -> Error {
        Error::InvalidData {
            origin: format!("{}:{}", self.origin, row.line),
            message,
        }
    }

    fn tool(&self, row: &ContactRow, name: &str, index: &BTreeMap<String, usize>) -> Result<usize> {
        index.get(name).copied().ok_or_else(|| {
            self.fail(
                row,
                format!(
                    "tool '{}' is not in the setup file's tools ({}); add it there with its link",
                    crate::limits::cut(name),
                    index.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            )
        })
    }

    fn plane(&mut self, row: &ContactRow) -> Result<ContactPlane> {
        if let Some((block, nominal)) = self.planes.get(&row.session) {
            return Ok(ContactPlane {
                block: *block,
                nominal: *nominal,
            });
        }
        let entry =
            self.setup.planes.get(&row.session).ok_or_else(|| {
                self.fail(
                    row,
                    format!(
                    "session '{}' has no plane in the setup file's planes ({}); add its nominal \
                     plane as a pose in the reference link",
                    crate::limits::cut(&row.session),
                    self.setup.planes.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
                )
            })?;
        let free = self.setup.free.plane;
        let block = self.add(
            format!("plane {}", row.session),
            &["height", "tilt a", "tilt b"],
            vec![0.0; 3],
            &[free; 3],
        );
        let nominal = self.world * entry.pose();
        self.planes.insert(row.session.clone(), (block, nominal));
        Ok(ContactPlane { block, nominal })
    }

    fn face(&mut self, row: &ContactRow) -> Result<ContactFace> {
        if let Some((block, nominal)) = self.faces.get(&row.tool) {
            return Ok(ContactFace {
                block: *block,
                nominal: *nominal,
            });
        }
        let face = self.setup.tools[&row.tool].face.ok_or_else(|| {
            self.fail(
                row,
                format!(
                    "a flush row needs tool '{}''s contact face: add 'face: {{xyz: [...], rpy: \
                     [...]}}' (its z axis the face normal) to the tool in the setup file",
                    row.tool
                ),
            )
        })?;
        let f = self.setup.free;
        let block = self.add(
            format!("face {}", row.tool),
            &["offset", "tilt a", "tilt b"],
            vec![0.0; 3],
            &[f.face_offset, f.face_tilt, f.face_tilt],
        );
        self.faces.insert(row.tool.clone(), (block, face.pose()));
        Ok(ContactFace {
            block,
            nominal: face.pose(),
        })
    }

    fn point(&mut self, row: &ContactRow, tool: &str) -> Result<usize> {
        if let Some(block) = self.points.get(tool) {
            return Ok(*block);
        }
        let point = self.setup.tools[tool].point.ok_or_else(|| {
            self.fail(
                row,
                format!(
                    "a {} row needs tool '{tool}''s contact point: add 'point: [x, y, z]' (m, in \
                     the tool's link) to the tool in the setup file",
                    row.kind.name()
                ),
            )
        })?;
        let free = self.setup.free.point;
        let block = self.add(
            format!("point {tool}"),
            &["x", "y", "z"],
            point.to_vec(),
            &[free; 3],
        );
        self.points.insert(tool.to_owned(), block);
        Ok(block)
    }

    fn contact(
        &mut self,
        row: &ContactRow,
        index: &BTreeMap<String, usize>,
    ) -> Result<(usize, Contact)> {
        let tool = self.tool(row, &row.tool, index)?;
        let second = match &row.tool2 {
            Some(name) => Some((name.clone(), self.tool(row, name, index)?)),
            None => None,
        };
        let contact = match (row.kind, second) {
            (ContactKind::Flush, _) => Contact::Flush {
                plane: self.plane(row)?,
                face: self.face(row)?,
            },
            (ContactKind::Point, _) => Contact::Point {
                plane: self.plane(row)?,
                point: self.point(row, &row.tool)?,
            },
            (ContactKind::Touch, Some((name, tool2))) => Contact::Touch {
                point: self.point(row, &row.tool)?,
                tool2,
                point2: self.point(row, &name)?,
            },
            (ContactKind::Distance, Some((name, tool2))) => {
                let bar = match self.bar {
                    Some(b) => b,
                    None => {
                        let bar = self.setup.bar.ok_or_else(|| {
                            self.fail(
                                row,
                                "a distance row needs the bar: add 'bar: {length: L}' (m) to the \
                                 setup file"
                                    .into(),
                            )
                        })?;
                        let block =
                            self.add("bar".into(), &["length"], vec![bar.length], &[bar.free]);
                        self.bar = Some(block);
                        block
                    }
                };
                Contact::Distance {
                    point: self.point(row, &row.tool)?,
                    tool2,
                    point2: self.point(row, &name)?,
                    length: bar,
                }
            }
            (kind, None) => {
                return Err(self.fail(row, format!("a {} row needs tool2", kind.name())))
            }
        };
        if contact.second_tool() == Some(tool) {
            return Err(self.fail(row, "tool and tool2 are the same tool".into()));
        }
        Ok((tool, contact))
    }
}
