//! `treecal simulate`: flags → [`SimulateConfig`] → [`simulate_with_progress`] → print, write.

use crate::cli::{MeasurementFormat, ObservationArg, PlanChoice, PosesFrom, SimulateArgs};
use crate::progress::Display;
use treecal::io::write_atomically;
use treecal::sim::ContactChoice;
use treecal::workflow::{self, simulate_with_progress, SimulateConfig};
use treecal::workflow::{PlanSource, RobotSource, StiffnessSource};
use treecal::Result;

/// The contacts and the one instrument (tracker, camera) of `--observation`'s list; contacts
/// mix with the camera simulation's instruments (`camera,touch`) and with a tracker of the
/// contact tools (`flush,tracker`: trial 1's tracker.csv written beside the contact files).
fn observations(
    list: &[ObservationArg],
) -> Result<(workflow::ObservationChoice, Vec<ContactChoice>, bool)> {
    let mut contacts = Vec::new();
    let mut instruments = Vec::new();
    for item in list {
        match item {
            ObservationArg::Flush => contacts.push(ContactChoice::Flush),
            ObservationArg::Plane => contacts.push(ContactChoice::Plane),
            ObservationArg::Touch => contacts.push(ContactChoice::Touch),
            ObservationArg::Bar => contacts.push(ContactChoice::Bar),
            ObservationArg::Tracker => instruments.push(workflow::ObservationChoice::Tracker),
            ObservationArg::Camera => instruments.push(workflow::ObservationChoice::Camera),
            ObservationArg::Mixed => instruments.push(workflow::ObservationChoice::Mixed),
            ObservationArg::RigidTracker => {
                instruments.push(workflow::ObservationChoice::RigidTracker)
            }
        }
    }
    contacts.dedup();
    let with_tracker = instruments.contains(&workflow::ObservationChoice::Tracker);
    if instruments.len() > 1 {
        return Err(treecal::Error::InvalidData {
            origin: "--observation".into(),
            message: "give one instrument (tracker, camera, mixed, rigid-tracker), a list of \
                      contacts (flush, plane, touch, bar), or contacts with one instrument \
                      (e.g. camera,touch or flush,tracker)"
                .into(),
        });
    }
    let contact_tracker = with_tracker && !contacts.is_empty();
    Ok((
        instruments.first().copied().unwrap_or_default(),
        contacts,
        contact_tracker,
    ))
}

fn config(args: SimulateArgs) -> Result<SimulateConfig> {
    let (observation, contacts, contact_tracker) = observations(&args.observation)?;
    Ok(SimulateConfig {
        robot: args.robot.map_or(RobotSource::BuiltIn, RobotSource::File),
        package_paths: args.package_path,
        collision_check: args.collision_check.into(),
        stiffness: args.stiffness.map(StiffnessSource::File),
        tools: args.tools,
        reference_link: args.reference_link,
        poses: args.poses as usize,
        torso_poses: args.torso_poses as usize,
        validation_poses: args.validation_poses as usize,
        trials: args.trials as usize,
        seed: args.seed,
        noise: args.noise,
        robust: args.robust.into(),
        outliers: args.outliers,
        outlier_size_mm: args.outlier_size,
        targets: args.targets,
        plan: match args.plan {
            PlanChoice::Staged => PlanSource::Staged,
            PlanChoice::Simultaneous => PlanSource::Simultaneous,
        },
        angle_error: args.angle_error,
        length_error: args.length_error,
        truth_harmonics: args.truth_harmonics,
        truth_backlash: args.truth_backlash,
        payload: args.payload,
        payloads: args.payloads.clone().unwrap_or_default(),
        joint_stiffness: args.joint_stiffness,
        model_stiffness_scale: args.model_stiffness_scale,
        identify_stiffness: args.identify_stiffness,
        poses_from: match args.poses_from {
            PosesFrom::Random => workflow::PosesFrom::Random,
            PosesFrom::Planned => workflow::PosesFrom::Planned,
        },
        candidates: args.candidates as usize,
        measurement_format: args.write_measurements.as_ref().map(|_| {
            match args.measurement_format {
                MeasurementFormat::Si => workflow::MeasurementFormat::Si,
                MeasurementFormat::Tracker => workflow::MeasurementFormat::Tracker,
            }
        }),
        observation,
        camera_link: args.camera_link,
        pixel_sigma: args.pixel_sigma,
        world_board: !args.no_world_board,
        estimate_intrinsics: args.estimate_intrinsics,
        contacts,
        encoder_noise: args.encoder_noise,
        contact_tables: (args.tables, if args.both_hands { 2 } else { 1 }),
        contact_tracker,
    })
}

pub fn run(args: SimulateArgs) -> Result<()> {
    let out = args.out.clone();
    let measurements = args.write_measurements.clone();
    let config = config(args)?;
    workflow::check_simulate_outputs(&config, &out, measurements.as_deref())?;
    let display = Display::new("simulate", config.trials > 1);
    let outcome = simulate_with_progress(&config, &|p| display.update(p));
    display.finish();
    let outcome = outcome?;
    for note in &outcome.notes {
        crate::output::note(note);
    }
    outcome.write(&out)?;
    if let (Some(path), Some(csv)) = (&measurements, &outcome.measurements_csv) {
        write_atomically(path, csv.as_bytes())?;
    }
    crate::output::print(&outcome.markdown)?;
    crate::output::note(format_args!("wrote {}", out.display()));
    Ok(())
}
