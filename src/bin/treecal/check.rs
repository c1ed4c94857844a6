//! `treecal check`: flags → [`CheckConfig`] → [`check`] → print.

use crate::cli::{AngleUnit, CheckArgs, Format, PlanChoice};
use treecal::workflow::{check, CheckConfig};
use treecal::workflow::{check_camera, CameraCheckConfig};
use treecal::workflow::{check_contacts, ContactCheckConfig};
use treecal::workflow::{MeasurementSource, PlanSource, RobotSource, StiffnessSource};
use treecal::Result;

fn config(args: CheckArgs) -> CheckConfig {
    CheckConfig {
        robot: args.robot.map_or(RobotSource::BuiltIn, RobotSource::File),
        tools: args.tools,
        reference_link: args.reference_link,
        pose_file: args.pose_file.or(args.poses),
        measurements: (!args.measurements.is_empty())
            .then(|| MeasurementSource::from_paths(args.measurements)),
        length_unit: args.length_unit,
        joint_length_unit: args.joint_length_unit,
        angle_unit: args.angle_unit.map(|unit| match unit {
            AngleUnit::Rad => treecal::io::AngleUnit::Radian,
            AngleUnit::Deg => treecal::io::AngleUnit::Degree,
        }),
        ignore_columns: args.ignore_columns,
        targets: args.targets,
        plan: match (args.plan, args.plan_file) {
            (_, Some(path)) => PlanSource::File(path),
            (Some(PlanChoice::Staged), None) => PlanSource::Staged,
            (Some(PlanChoice::Simultaneous), None) => PlanSource::Simultaneous,
            (None, None) => PlanSource::Auto,
        },
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
        condition_limit: args.condition_limit,
        seed: args.seed,
        identify_stiffness: args.identify_stiffness,
        stiffness: args.stiffness.map(StiffnessSource::File),
        payloads: args.payloads,
        stiffness_prior: args.stiffness_prior,
    }
}

/// Prints a camera or contact check: its notes on stderr, then its text or its report as
/// YAML or JSON.
fn print_outcome<T: serde::Serialize>(
    notes: &[treecal::workflow::Note],
    text: String,
    report: &T,
    format: Format,
) -> Result<()> {
    for note in notes {
        crate::output::note(note);
    }
    let text = match format {
        Format::Text => text,
        Format::Yaml => treecal::io::to_yaml(report)?,
        Format::Json => treecal::io::to_json(report)?,
    };
    crate::output::print(&text)
}

pub fn run(args: CheckArgs) -> Result<()> {
    let format = args.format;
    if let (Some(camera_file), Some(detections)) = (args.camera.clone(), args.detections.clone()) {
        let outcome = check_camera(&CameraCheckConfig {
            robot: args.robot.map_or(RobotSource::BuiltIn, RobotSource::File),
            tools: args.tools,
            camera_file,
            detections,
            pixel_sigma: args.pixel_sigma,
        })?;
        return print_outcome(&outcome.notes, outcome.text, &outcome.report, format);
    }
    if let (Some(contacts), Some(setup)) = (args.contacts.clone(), args.contact_setup.clone()) {
        let outcome = check_contacts(&ContactCheckConfig {
            robot: args.robot.map_or(RobotSource::BuiltIn, RobotSource::File),
            contacts,
            setup,
            reference_link: args.reference_link,
        })?;
        return print_outcome(&outcome.notes, outcome.text, &outcome.report, format);
    }
    let outcome = check(&config(args))?;
    for note in &outcome.notes {
        crate::output::note(note);
    }
    let text = match format {
        Format::Text => outcome.text,
        Format::Yaml => outcome.to_yaml()?,
        Format::Json => outcome.to_json()?,
    };
    crate::output::print(&text)?;
    Ok(())
}
