//! The one way treecal parses its YAML files (plans, registrations, stiffness, parameters,
//! MCPC tables): size and depth checked first ([`crate::limits::check_yaml_depth`]), the
//! file's structs deny unknown keys (`#[serde(deny_unknown_fields)]`), and serde's message is
//! made one a user can act on: an unknown key or value names the closest valid one, no value
//! is quoted at full length and no number prints with hundreds of digits.

use crate::error::{closest, Error, Result};
use crate::limits::{check_yaml_depth, cut};
use serde::de::DeserializeOwned;

/// Parses YAML `text` into `T`; `origin` names the file. A failure is an
/// [`Error::InvalidData`] at `origin:line:column` whose message is serde's (see
/// [`readable_message`]) followed by `hint` (e.g. "; see docs/file-formats.md").
pub(crate) fn parse_yaml<T: DeserializeOwned>(text: &str, origin: &str, hint: &str) -> Result<T> {
    check_yaml_depth(text, origin)?;
    serde_yaml::from_str(text).map_err(|e| Error::InvalidData {
        origin: match e.location() {
            Some(l) => format!("{origin}:{}:{}", l.line(), l.column()),
            None => origin.to_owned(),
        },
        message: format!("{}{hint}", readable_message(&e.to_string())),
    })
}

/// serde_yaml's message without its trailing " at line L column C" (the origin carries it),
/// an unknown key or variant with the closest valid one named, long quoted values cut, and
/// numbers of more than 20 digits in exponent notation.
pub(crate) fn readable_message(message: &str) -> String {
    let message = match message.rfind(" at line ") {
        Some(at) if message[at..].contains(" column ") => &message[..at],
        _ => message,
    };
    let message = suggest_closest(message).unwrap_or_else(|| message.to_owned());
    tame_numbers(&cut_quoted(&message))
}

/// "unknown field `stagez`, expected `stages`" → "unknown key 'stagez'; the closest valid key
/// is 'stages' (valid here: stages)"; the same for unknown variants (values).
fn suggest_closest(message: &str) -> Option<String> {
    let (prefix, kind, rest) = ["unknown field `", "unknown variant `"]
        .iter()
        .find_map(|p| {
            let at = message.find(p)?;
            Some((&message[..at], *p, &message[at + p.len()..]))
        })?;
    let (name, rest) = rest.split_once('`')?;
    let valid: Vec<&str> = rest.split('`').skip(1).step_by(2).collect();
    let what = if kind.contains("field") {
        "key"
    } else {
        "value"
    };
    let name = cut(name);
    Some(match closest(&name, valid.iter().copied()) {
        Some(best) => format!(
            "{prefix}unknown {what} '{name}'; the closest valid {what} is '{best}' (valid \
             here: {})",
            valid.join(", ")
        ),
        None => format!("{prefix}unknown {what} '{name}'; this place takes no {what}s"),
    })
}

/// Backquoted values (serde quotes the offending value so) cut to
/// [`crate::limits::MAX_QUOTED_CHARS`].
fn cut_quoted(message: &str) -> String {
    let mut out = String::new();
    for (i, part) in message.split('`').enumerate() {
        if i > 0 {
            out.push('`');
        }
        if i % 2 == 1 {
            out.push_str(&cut(part));
        } else {
            out.push_str(part);
        }
    }
    out
}

/// Runs of more than 20 digits (as serde prints 1e300) in exponent notation.
pub(crate) fn tame_numbers(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(start) = rest.find(|c: char| c.is_ascii_digit()) {
        out.push_str(&rest[..start]);
        let tail = &rest[start..];
        let end = tail
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(tail.len());
        let number = &tail[..end];
        let digits = number.chars().filter(char::is_ascii_digit).count();
        match number.parse::<f64>() {
            Ok(value) if digits > 20 => out.push_str(&format!("{value:e}")),
            _ => out.push_str(number),
        }
        rest = &tail[end..];
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Stage {
        name: String,
        measurements: Option<String>,
    }

    #[test]
    fn unknown_keys_name_the_closest() {
        let error = parse_yaml::<Vec<Stage>>("- name: a\n  mesurements: torso\n", "p.yaml", "")
            .unwrap_err()
            .to_string();
        assert!(
            error.starts_with("p.yaml:2:")
                && error
                    .contains("unknown key 'mesurements'; the closest valid key is 'measurements'"),
            "{error}"
        );
        assert!(parse_yaml::<Vec<Stage>>("- name: a\n  measurements: torso\n", "p", "").is_ok());
    }

    #[test]
    fn long_values_and_huge_numbers_are_cut() {
        let long = format!("- name: [{}]\n", "x".repeat(1000));
        let error = parse_yaml::<Vec<Stage>>(&long, "p", "")
            .unwrap_err()
            .to_string();
        assert!(error.len() < 300, "{error}");
        assert_eq!(
            tame_numbers(&format!("value {}0.0 here, 12 ok", "1".repeat(300))),
            format!(
                "value {:e} here, 12 ok",
                format!("{}0.0", "1".repeat(300)).parse::<f64>().unwrap()
            )
        );
        let huge = parse_yaml::<Vec<Stage>>("- name: 1e300\n", "p", "");
        if let Err(e) = huge {
            assert!(e.to_string().len() < 200, "{e}");
        }
    }
}
