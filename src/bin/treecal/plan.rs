//! `treecal plan`: flags → [`PlanConfig`] → [`plan_with_progress`] → print, write the CSV.

use crate::cli::{CriterionChoice, PlanArgs, StageChoice};
use crate::progress::Display;
use treecal::calibration::Criterion;
use treecal::workflow::plan::{self, plan_with_progress, PlanConfig, PlanStage};
use treecal::workflow::source::RobotSource;
use treecal::Result;

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
        criterion: match args.criterion {
            CriterionChoice::O1 => Criterion::O1,
            CriterionChoice::D => Criterion::D,
            CriterionChoice::O3 => Criterion::O3,
        },
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

pub fn run(args: PlanArgs) -> Result<()> {
    let out = args.out.clone();
    let config = config(args);
    plan::check_output(&config, &out)?;
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
