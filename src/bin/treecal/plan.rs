//! `treecal plan`: flags → [`PlanConfig`] → [`plan_with_progress`] → print, write the CSV.

use crate::cli::{CriterionChoice, PlanArgs, StageChoice};
use crate::progress::Display;
use treecal::calibration::Criterion;
use treecal::sim::ContactChoice;
use treecal::workflow::RobotSource;
use treecal::workflow::{self, plan_with_progress, PlanConfig, PlanStage};
use treecal::workflow::{check_camera_plan_output, plan_camera, CameraPlanConfig};
use treecal::workflow::{check_contact_plan_output, plan_contacts, ContactPlanConfig};
use treecal::{Error, Result};

fn config(args: PlanArgs) -> PlanConfig {
    PlanConfig {
        robot: args.robot.map_or(RobotSource::BuiltIn, RobotSource::File),
        package_paths: args.package_path,
        collision_check: args.collision_check.into(),
        tools: args.tools,
        reference_link: args.reference_link,
        poses: args.poses as usize,
        torso_poses: args.torso_poses as usize,
        candidates: args.candidates as usize,
        criterion: criterion(args.criterion),
        targets: args.targets,
        stage: match args.stage {
            StageChoice::All => PlanStage::All,
            StageChoice::Arms => PlanStage::Arms,
            StageChoice::Torso => PlanStage::Torso,
            StageChoice::Staged => PlanStage::Staged,
        },
        workspace: args.workspace,
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
        noise: args.noise,
        seed: args.seed,
    }
}

/// `plan --camera`: the camera plan.
fn run_camera(args: PlanArgs, camera: std::path::PathBuf) -> Result<()> {
    let out = args.out.clone();
    let config = CameraPlanConfig {
        robot: args.robot.map_or(RobotSource::BuiltIn, RobotSource::File),
        package_paths: args.package_path,
        collision_check: args.collision_check.into(),
        tools: args.tools,
        camera_file: camera,
        poses: args.poses as usize,
        candidates: args.candidates as usize,
        criterion: criterion(args.criterion),
        pixel_sigma: args.pixel_sigma,
        max_view_angle: args.max_view_angle.to_radians(),
        seed: args.seed,
    };
    check_camera_plan_output(&config, &out)?;
    let display = Display::new("plan", true);
    let outcome = plan_camera(&config, &|p| display.update(p));
    display.finish();
    let outcome = outcome?;
    outcome.write(&out)?;
    report(&outcome.text, &outcome.notes, &out)
}

/// Prints a plan's summary and notes and names the written file.
fn report(text: &str, notes: &[treecal::workflow::Note], out: &std::path::Path) -> Result<()> {
    crate::output::print(text)?;
    for note in notes {
        crate::output::note(note);
    }
    crate::output::note(format_args!("wrote {}", out.display()));
    Ok(())
}

/// `plan --contact-setup`: the contact plan.
fn run_contacts(args: PlanArgs, setup: std::path::PathBuf) -> Result<()> {
    let out = args.out.clone();
    let kinds = args
        .observation
        .unwrap_or_default()
        .iter()
        .map(|name| {
            ContactChoice::parse(name.trim()).ok_or_else(|| Error::InvalidSetting {
                setting: "observation".into(),
                message: format!("'{name}' is not a contact kind; use flush, plane, touch or bar"),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let config = ContactPlanConfig {
        robot: args.robot.map_or(RobotSource::BuiltIn, RobotSource::File),
        setup,
        kinds,
        tools: args.tools,
        reference_link: args.reference_link,
        poses: args.poses as usize,
        candidates: args.candidates as usize,
        criterion: criterion(args.criterion),
        seed: args.seed,
        package_paths: args.package_path,
        collision_check: args.collision_check.into(),
    };
    check_contact_plan_output(&config, &out)?;
    let display = Display::new("plan", true);
    let outcome = plan_contacts(&config, &|p| display.update(p));
    display.finish();
    let outcome = outcome?;
    outcome.write(&out)?;
    report(&outcome.text, &outcome.notes, &out)
}

fn criterion(choice: CriterionChoice) -> Criterion {
    match choice {
        CriterionChoice::O1 => Criterion::O1,
        CriterionChoice::D => Criterion::D,
        CriterionChoice::O3 => Criterion::O3,
    }
}

pub fn run(args: PlanArgs) -> Result<()> {
    if let Some(camera) = args.camera.clone() {
        return run_camera(args, camera);
    }
    if let Some(setup) = args.contact_setup.clone() {
        return run_contacts(args, setup);
    }
    let out = args.out.clone();
    let config = config(args);
    workflow::check_output(&config, &out)?;
    let display = Display::new("plan", true);
    let outcome = plan_with_progress(&config, &|p| display.update(p));
    display.finish();
    let outcome = outcome?;
    outcome.write(&out)?;
    crate::output::print(&outcome.text)?;
    for note in &outcome.notes {
        crate::output::note(note);
    }
    crate::output::note(format_args!("wrote {}", out.display()));
    Ok(())
}
