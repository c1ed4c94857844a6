//! The one table from the library's settings to this command line's flags.
//!
//! The library names a setting by its snake_case name (`length_unit`, in backticks inside a
//! message, see [`treecal::Error::InvalidSetting`]); every setting is a long flag of some
//! subcommand, spelled in kebab case (`--length-unit`). The table is read from the clap
//! definitions, so a new flag is in it the moment it exists.

use clap::CommandFactory;
use std::collections::BTreeMap;
use std::sync::OnceLock;

/// Setting name → flag, for every long flag of every subcommand.
fn table() -> &'static BTreeMap<String, String> {
    static TABLE: OnceLock<BTreeMap<String, String>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let cli = crate::cli::Cli::command();
        cli.get_subcommands()
            .flat_map(|command| command.get_arguments())
            .filter_map(|argument| argument.get_long())
            .map(|long| (long.replace('-', "_"), format!("--{long}")))
            .collect()
    })
}

/// The flag that sets `setting` (`length_unit` → `--length-unit`), if the command line has one.
pub fn flag(setting: &str) -> Option<&'static str> {
    table().get(setting).map(String::as_str)
}

/// `text` (a message of the library) with the settings it names spelled as flags.
pub fn with_flags(text: &str) -> String {
    treecal::error::name_settings(text, |setting| flag(setting).map(str::to_owned))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_the_library_names_have_flags() {
        for setting in [
            "length_unit",
            "angle_unit",
            "joint_length_unit",
            "measurement_frame",
            "position_sigma",
            "rotation_sigma",
            "tracker_columns",
            "tracker_rate",
            "noise",
            "tools",
            "out",
            "max_error",
            "cv",
            "model",
            "robust",
            "collision_check",
            "pose_file",
            "clock_offset",
            "freeze",
        ] {
            assert_eq!(
                flag(setting),
                Some(format!("--{}", setting.replace('_', "-")).as_str()),
                "{setting}"
            );
        }
        let error = treecal::Error::setting("length_unit", "'cm': give `angle_unit` or `fit`");
        assert_eq!(
            with_flags(&error.to_string()),
            "--length-unit: 'cm': give --angle-unit or `fit`"
        );
    }
}
