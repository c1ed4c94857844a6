//! The measurement CSV read from a file line by line (a plain file) must give what its text
//! read whole gives: the same set, warnings and notes, or the same error message.

use crate::common::*;
use treecal::io::{
    measured_targets, measured_tool_names, parse_measurements, read_measured_targets,
    read_measured_tool_names, read_measurements, MeasurementReadOptions,
};

const HEADER: &str = "id,stage,tool,torso_joint1,torso_joint2,left_joint1,left_joint2,left_joint3,left_joint4,left_joint5,left_joint6,x,y,z";

/// `count` left-arm rows (row `i` at joint values `0.01·i`), the third repeating the second.
fn rows(count: usize) -> Vec<String> {
    (1..=count)
        .map(|i| {
            let v = if i == 3 { 0.02 } else { 0.01 * i as f64 };
            format!(
                "{i},arms,left_tool,{v},{v},{v},{v},{v},{v},{v},{v},{},2,3",
                i % 5
            )
        })
        .collect()
}

/// Reads `text` from a file and whole, and checks both ways give the same.
fn assert_same_both_ways(text: &str, options: &MeasurementReadOptions, what: &str) {
    let (tree, model) = robonaut_model();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.csv");
    std::fs::write(&path, text).unwrap();
    let origin = path.display().to_string();
    let from_file = read_measurements(&path, &tree, &model, options).map_err(|e| e.to_string());
    let whole =
        parse_measurements(text, &origin, &tree, &model, options).map_err(|e| e.to_string());
    assert_eq!(from_file, whole, "{what}");
    let targets = read_measured_targets(&path).map_err(|e| e.to_string());
    let whole_targets = measured_targets(text, &origin).map_err(|e| e.to_string());
    assert_eq!(targets, whole_targets, "{what}: targets");
    let tools = read_measured_tool_names(&path).map_err(|e| e.to_string());
    let whole_tools = measured_tool_names(text, &origin).map_err(|e| e.to_string());
    assert_eq!(tools, whole_tools, "{what}: tool names");
}

#[test]
fn a_file_read_line_by_line_gives_what_its_text_gives() {
    let body = rows(6).join("\n");
    let plain = format!("# units: length=mm angle=rad\n{HEADER}\n{body}\n");
    let strict = MeasurementReadOptions {
        strict_limits: true,
        ..Default::default()
    };
    let cases = [
        ("plain", plain.clone()),
        ("CRLF", plain.replace('\n', "\r\n")),
        ("byte-order mark", format!("\u{feff}{plain}")),
        ("two marks", format!("\u{feff}\u{feff}{plain}")),
        ("no final break", plain.trim_end().to_owned()),
        (
            "comments, blank and empty rows, spaces",
            format!(
                "\n# hello\n {HEADER} \n\n,,,\n# c\n{}\n",
                rows(4).join("\n\n")
            ),
        ),
        ("quoted", plain.replace("left_tool", "\"left_tool\"")),
        ("lone CR", plain.replacen('\n', "\r", 3)),
        ("bad value", plain.replace("0.04", "x")),
        ("too many fields", plain.replace(",2,3", ",2,3,4")),
        ("repeated id", plain.replace("\n5,", "\n4,")),
        ("header only", format!("{HEADER}\n")),
        ("empty", String::new()),
        ("two unit comments", format!("# units: length=mm\n{plain}")),
        ("outside limits", plain.replace("0.06", "9")),
    ];
    for (what, text) in &cases {
        assert_same_both_ways(text, &MeasurementReadOptions::default(), what);
        assert_same_both_ways(text, &strict, what);
    }
}

/// A file of several blocks (the reader parses blocks of about 1 MB in parallel): the rows,
/// ids, warnings and errors are what the whole text gives, an error in a late block naming
/// its line.
#[test]
fn a_file_of_many_blocks_read_in_parallel_gives_what_its_text_gives() {
    let count = 40_000;
    let body = rows(count).join("\n");
    let plain = format!("# units: length=mm angle=rad\n{HEADER}\n{body}\n");
    assert!(plain.len() > 3 << 20, "{} bytes", plain.len());
    let late = format!("\n{},", count - 5);
    // Copies of rows 10 and 20000 under new ids.
    let copy_of = |row: usize, id: usize| {
        let line = plain.lines().nth(row + 1).unwrap_or_default();
        format!("{id}{}", &line[line.find(',').unwrap_or(0)..])
    };
    let (thrice, twice, thrice_again) = (
        copy_of(10, count + 1),
        copy_of(20_000, count + 2),
        copy_of(10, count + 3),
    );
    let no_id: String = plain
        .lines()
        .map(|line| line.split_once(',').map_or(line, |(_, rest)| rest))
        .collect::<Vec<_>>()
        .join("\n");
    let cases = [
        ("plain", plain.clone()),
        ("no id column", no_id),
        (
            "bad value late",
            plain.replacen(
                &format!("{late}arms,left_tool,"),
                &format!("{late}arms,left_tool,x"),
                1,
            ),
        ),
        (
            "id repeated across blocks",
            plain.replacen(&late, "\n7,", 1),
        ),
        (
            "row repeated across blocks",
            plain.replacen(
                &late,
                &format!(
                    "{late}arms,left_tool,0.01,0.01,0.01,0.01,0.01,0.01,0.01,0.01,1,2,3\n{}0,",
                    count - 5
                ),
                1,
            ),
        ),
        (
            "quote late",
            plain.replacen(&late, &format!("{late}\"arms\""), 1),
        ),
        (
            "a row repeated thrice, another twice, across blocks",
            plain.replacen(
                &late,
                &format!("\n{thrice}\n{twice}\n{thrice_again}{late}"),
                1,
            ),
        ),
    ];
    for (what, text) in &cases {
        assert_same_both_ways(text, &MeasurementReadOptions::default(), what);
    }
    let (tree, model) = robonaut_model();
    let repeated = parse_measurements(&cases[6].1, "f", &tree, &model, &Default::default());
    let warnings = repeated.map(|set| set.warnings).unwrap_or_default();
    assert!(
        warnings.iter().any(
            |w| w.contains("the row repeats line 12") && w.contains("(3 repeated rows in all)")
        ),
        "{warnings:?}"
    );
    let late_line = 2 + count - 5;
    let bad = &cases[2].1;
    let error = parse_measurements(bad, "f", &tree, &model, &Default::default()).unwrap_err();
    assert!(
        error.to_string().starts_with(&format!("f:{late_line}:")),
        "{error}"
    );
}
