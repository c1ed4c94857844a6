//! `treecal verify`: flags → [`VerifyConfig`] → [`treecal::workflow::verify`] → notes on
//! stderr, report.md on stdout, the files in `--out`; exit 1 above `--max-error`.

use crate::cli::GravityFrame;
use crate::cli_trust::{FrameArg, VerifyArgs};
use treecal::workflow::{verify, MeasurementSource, StiffnessSource, VerifyConfig, VerifyFrame};
use treecal::{Error, Result};

pub fn run(args: VerifyArgs) -> Result<()> {
    let config = VerifyConfig {
        calibration: args.calibration,
        robot: args.robot,
        registration: args.registration,
        stiffness: args.stiffness.map(StiffnessSource::File),
        measurements: MeasurementSource::from_paths(args.measurements),
        tools: args.tools,
        length_unit: args.length_unit,
        angle_unit: args.angle_unit,
        joint_length_unit: args.joint_length_unit,
        frame: match args.frame {
            FrameArg::Fit => VerifyFrame::Fit,
            FrameArg::Registration => VerifyFrame::Registration,
            FrameArg::Base => VerifyFrame::Base,
        },
        gravity_frame: match args.gravity_frame {
            GravityFrame::Measurement => treecal::workflow::GravityFrame::Measurement,
            GravityFrame::Base => treecal::workflow::GravityFrame::Base,
        },
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
        max_error_mm: args.max_error,
    };
    let mut verification = verify(&config)?;
    // report.md and report.html say the flags, as stdout does.
    let flag = |setting: &str| crate::settings::flag(setting).map(str::to_owned);
    treecal::workflow::spell_reports(&mut verification.files, &flag);
    for note in &verification.notes {
        crate::output::note(note);
    }
    verification.write(&args.out)?;
    crate::output::print(&verification.markdown)?;
    crate::output::note(format_args!("wrote {}", args.out.display()));
    if !verification.passed() {
        return Err(Error::InvalidData {
            origin: "verify".into(),
            message: verification.report.verdict.sentence(),
        });
    }
    Ok(())
}
