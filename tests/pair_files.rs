//! `treecal pair`'s inputs as files: a ROS 2 bag (MCAP, written here with the `mcap` crate's
//! writer), vendor column names, bad files (errors naming file and line, never a panic), and
//! the CLI end to end: the CSV it writes calibrates.

use crate::common::cli::{assert_error, assert_success, treecal};
use crate::pair::{logs, moving, robonaut};
use crate::pair_logs::{Motion, Recording};
use std::collections::BTreeMap;
use std::path::Path;
use treecal::workflow::pair;

/// A little-endian CDR JointState (rclcpp's layout; velocity and effort empty).
fn joint_state(stamp: f64, names: &[String], positions: &[f64]) -> Vec<u8> {
    let mut out = vec![0, 1, 0, 0];
    fn align(out: &mut Vec<u8>, n: usize) {
        while (out.len() - 4) % n != 0 {
            out.push(0);
        }
    }
    fn string(out: &mut Vec<u8>, s: &str) {
        align(out, 4);
        out.extend((s.len() as u32 + 1).to_le_bytes());
        out.extend(s.as_bytes());
        out.push(0);
    }
    let sec = stamp.floor();
    out.extend((sec as i32).to_le_bytes());
    out.extend(
        (((stamp - sec) * 1e9).round() as u32)
            .min(999_999_999)
            .to_le_bytes(),
    );
    string(&mut out, "");
    align(&mut out, 4);
    out.extend((names.len() as u32).to_le_bytes());
    for name in names {
        string(&mut out, name);
    }
    align(&mut out, 4);
    out.extend((positions.len() as u32).to_le_bytes());
    for p in positions {
        align(&mut out, 8);
        out.extend(p.to_le_bytes());
    }
    for _ in 0..2 {
        align(&mut out, 4);
        out.extend(0u32.to_le_bytes());
    }
    out
}

/// Writes `messages` (stamp, names, positions) on `/joint_states` into an MCAP file, plus
/// one message of another type on `/tf`.
fn write_bag(path: &Path, messages: &[(f64, Vec<String>, Vec<f64>)]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut writer = mcap::Writer::new(file).unwrap();
    let schema = writer
        .add_schema("sensor_msgs/msg/JointState", "ros2msg", b"std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort")
        .unwrap();
    let channel = writer
        .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
        .unwrap();
    let other = writer
        .add_schema("tf2_msgs/msg/TFMessage", "ros2msg", b"")
        .unwrap();
    let tf = writer
        .add_channel(other, "/tf", "cdr", &BTreeMap::new())
        .unwrap();
    for (sequence, (stamp, names, positions)) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: sequence as u32,
            log_time: (stamp * 1e9) as u64,
            publish_time: (stamp * 1e9) as u64,
        };
        writer
            .write_to_known_channel(&header, &joint_state(*stamp, names, positions))
            .unwrap();
        if sequence == 3 {
            let header = mcap::records::MessageHeader {
                channel_id: tf,
                ..header
            };
            writer.write_to_known_channel(&header, &[1, 2, 3]).unwrap();
        }
    }
    writer.finish().unwrap();
}

#[test]
fn a_ros2_bag_pairs_like_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let tree = robonaut();
    let (dofs, names) = moving(&tree, "left_tool");
    let motion = Motion::new(&tree, &dofs, 10, false, 21);
    let recording = Recording {
        joint_zero: 1.7e9,
        ..Recording::default()
    };
    let mut config = logs(dir.path(), "left_tool", &motion, &recording);
    // A gripper joint the URDF does not have rides along, as in real bags.
    let mut all = names.clone();
    all.push("gripper_finger".into());
    let messages: Vec<_> = recording
        .joint_samples(&motion)
        .into_iter()
        .map(|(t, q)| {
            let mut values: Vec<f64> = dofs.iter().map(|&d| q[d]).collect();
            values.push(0.01);
            (t, all.clone(), values)
        })
        .collect();
    let from_csv = pair(&config).unwrap();
    config.joints = dir.path().join("joints.mcap");
    write_bag(&config.joints, &messages);
    let from_bag = pair(&config).unwrap();
    assert!((from_bag.offset - recording.offset()).abs() < 1.0 / recording.tracker_rate);
    assert_eq!(from_bag.kept(), from_csv.kept());
    assert!(
        from_bag
            .notes
            .iter()
            .any(|n| n.text.contains("gripper_finger")),
        "{:?}",
        from_bag.notes
    );
    // Two publishers on one topic (torso and arm controllers): each message gives some joints.
    let split: Vec<_> = messages
        .iter()
        .flat_map(|(t, names, values)| {
            [
                (*t, names[..2].to_vec(), values[..2].to_vec()),
                (t + 0.002, names[2..].to_vec(), values[2..].to_vec()),
            ]
        })
        .collect();
    write_bag(&config.joints, &split);
    let from_split = pair(&config).unwrap();
    assert!((from_split.offset - recording.offset()).abs() < 1.0 / recording.tracker_rate);
    assert_eq!(from_split.kept(), from_csv.kept());
    // Nanosecond stamps against 1e-6 s CSV times: the same rows to far below the noise.
    let rows = |csv: &str| {
        csv.lines()
            .filter(|l| l.starts_with("left_tool-"))
            .map(String::from)
            .collect::<Vec<_>>()
    };
    for (a, b) in rows(&from_csv.csv).iter().zip(rows(&from_bag.csv)) {
        let (a, b): (Vec<&str>, Vec<&str>) = (a.split(',').collect(), b.split(',').collect());
        for (x, y) in a[2..].iter().zip(&b[2..]) {
            let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            assert!((x - y).abs() < 1e-4, "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn damaged_bags_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let names = vec!["torso_joint1".to_string()];
    let messages: Vec<_> = (0..50)
        .map(|k| (k as f64 * 0.01, names.clone(), vec![0.1]))
        .collect();
    let bag = dir.path().join("bag.mcap");
    write_bag(&bag, &messages);
    let bytes = std::fs::read(&bag).unwrap();
    let cut = dir.path().join("cut.mcap");
    let options = treecal::io::JointLogOptions::default();
    for end in [9, 40, bytes.len() / 2, bytes.len() - 3] {
        std::fs::write(&cut, &bytes[..end]).unwrap();
        let error = treecal::io::read_joint_log(&cut, &options)
            .unwrap_err()
            .to_string();
        assert!(error.contains("cut.mcap"), "{end}: {error}");
    }
    // Garbage inside a JointState message.
    let bad: Vec<_> = (0..5)
        .map(|k| (k as f64, vec!["a".to_string(); 2], vec![0.1]))
        .collect();
    write_bag(&bag, &bad);
    let error = treecal::io::read_joint_log(&bag, &options)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("bag.mcap: message 1") && error.contains("2 names but 1 positions"),
        "{error}"
    );
    // Damaged bytes anywhere: an error or a log, never a panic.
    let mut state = 3u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as usize
    };
    for _ in 0..300 {
        let mut damaged = bytes.clone();
        for _ in 0..1 + next() % 3 {
            let at = next() % damaged.len();
            damaged[at] = next() as u8;
        }
        std::fs::write(&cut, &damaged).unwrap();
        let _ = treecal::io::read_joint_log(&cut, &options);
    }
    let missing = treecal::io::JointLogOptions {
        topic: Some("/joint_state".into()),
        ..options
    };
    write_bag(&bag, &messages);
    let error = treecal::io::read_joint_log(&bag, &missing)
        .unwrap_err()
        .to_string();
    assert!(error.contains("/joint_states (50 messages)"), "{error}");
}

#[test]
fn bad_logs_are_errors_naming_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path.display().to_string()
    };
    let tracker = write("t.csv", "time,x,y,z\n0,1,2,3\n0.1,1,2,3\n0.2,1,2,3\n");
    let joints = write("j.csv", "time,torso_joint1\n0,0.1\n0.01,abc\n");
    let out = dir.path().join("m.csv");
    let out = out.to_str().unwrap();
    let run = |joints: &str, tracker: &str, extra: &[&str]| {
        let mut args = vec![
            "pair",
            "--joints",
            joints,
            "--tracker",
            tracker,
            "--tool",
            "left_tool",
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        treecal(&args)
    };
    assert_error(
        &run(&joints, &tracker, &[]),
        &["j.csv:3:torso_joint1", "'abc' is not a finite number"],
        "bad value",
    );
    let backwards = write("b.csv", "time,torso_joint1\n0,0.1\n# a comment\n-1,0.1\n");
    assert_error(
        &run(&backwards, &tracker, &[]),
        &["b.csv:4:time", "time order"],
        "time order",
    );
    let no_time = write("n.csv", "stamp,torso_joint1\n0,0.1\n");
    assert_error(
        &run(&no_time, &tracker, &[]),
        &["n.csv:1", "--joints-time-column"],
        "no time",
    );
    let good = write(
        "g.csv",
        "time,torso_joint1,torso_joint2\n0,0.1,0\n0.01,0.1,0\n",
    );
    assert_error(
        &run(&good, &tracker, &[]),
        &["g.csv", "left_joint1"],
        "joints moving the tool missing",
    );
    let vicon = write("v.csv", "Frame,TX,TY,TZ\n1,1,2,3\n");
    assert_error(
        &run(&good, &vicon, &[]),
        &["v.csv:1", "--tracker-columns"],
        "tracker columns",
    );
    let half_pose = write("h.csv", "time,x,y,z,qw,qx\n0,1,2,3,1,0\n");
    assert_error(
        &run(&good, &half_pose, &[]),
        &["h.csv:1", "'qy' (qy)"],
        "half a quaternion",
    );
    let bad_q = write(
        "q.csv",
        "time,x,y,z,qw,qx,qy,qz\n0,1,2,3,1,0,0,0\n0.1,1,2,3,0.5,0.1,0,0\n",
    );
    assert_error(
        &run(&good, &bad_q, &[]),
        &["q.csv:3", "norm"],
        "quaternion norm",
    );
    assert_error(
        &run(&good, &tracker, &["--tracker-columns", "t=Frame"]),
        &["--tracker-columns", "unknown key 't'"],
        "mapping",
    );
    let mm = write(
        "mm.csv",
        "# units: length=mm\ntime,x,y,z\n0,1,2,3\n0.1,1,2,3\n",
    );
    assert_error(
        &run(&good, &mm, &["--length-unit", "m"]),
        &["mm.csv:1", "contradicts"],
        "units",
    );
    assert!(!Path::new(out).exists());
}

/// Both arms paired by the CLI from vendor-named tracker exports (mm), concatenated, then
/// calibrated: the verdict is ok and the fit reaches the noise.
#[test]
fn the_paired_csv_calibrates() {
    let dir = tempfile::tempdir().unwrap();
    let tree = robonaut();
    let mut combined = String::new();
    for (k, tool) in ["left_tool", "right_tool"].into_iter().enumerate() {
        // The joint log gives every joint, as joint_state_broadcaster does, so that the two
        // CSVs have the same columns.
        let (dofs, _) = moving(&tree, tool);
        let every: Vec<usize> = (0..tree.dof_count()).collect();
        let names: Vec<String> = tree
            .dofs()
            .iter()
            .map(|&j| tree.joint(j).name.clone())
            .collect();
        let motion = Motion::new(&tree, &dofs, 26, false, 40 + k as u64);
        let recording = Recording {
            seed: 50 + k as u64,
            ..Recording::default()
        };
        let joints = dir.path().join(format!("{tool}_joints.csv"));
        let tracker = dir.path().join(format!("{tool}_tracker.csv"));
        std::fs::write(&joints, recording.joint_csv(&motion, &every, &names)).unwrap();
        let header = ["Time", "TX", "TY", "TZ", "RW", "RX", "RY", "RZ"];
        std::fs::write(
            &tracker,
            recording.tracker_csv(&motion, &tree, tool, header),
        )
        .unwrap();
        let out = dir.path().join(format!("{tool}.csv"));
        let run = treecal(&[
            "pair",
            "--joints",
            joints.to_str().unwrap(),
            "--tracker",
            tracker.to_str().unwrap(),
            "--tool",
            tool,
            "--tracker-columns",
            "time=Time,x=TX,y=TY,z=TZ,qw=RW,qx=RX,qy=RY,qz=RZ",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_success(&run, "pair");
        assert!(!run.stderr.contains("warning"), "{run}");
        assert!(dir.path().join(format!("{tool}.pairing.md")).is_file());
        let text = std::fs::read_to_string(&out).unwrap();
        // The second file's units, comments and header are the first's.
        let body: Vec<&str> = text
            .lines()
            .filter(|l| !l.starts_with('#'))
            .skip(usize::from(k > 0))
            .collect();
        if k == 0 {
            combined += text.lines().next().unwrap();
            combined += "\n";
        }
        combined += &(body.join("\n") + "\n");
    }
    let measurements = dir.path().join("measurements.csv");
    std::fs::write(&measurements, combined).unwrap();
    let out = dir.path().join("calibrated");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        measurements.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_success(&run, "calibrate");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    // The logs come from the nominal robot, so there is nothing to correct: the calibrated URDF
    // ties the registered nominal robot within the noise, which is no `urdf-alone-worse`
    // warning (no false alarm on good data), and the held-out error is the averaged noise.
    assert_ne!(report["verdict"]["status"], "failed", "{run}");
    assert!(!run.stderr.contains("do not use it alone"), "{run}");
    let codes = report["verdict"]["reasons"].to_string();
    assert!(!codes.contains("urdf-alone-worse"), "{codes}");
    assert!(run.stdout.contains("RMS position error 0.00"), "{run}");
}

/// The CLI's refusals exit 1 and write nothing: an ambiguous offset (repetitive motion), and
/// thresholds no plateau meets (each rejection's reason named).
#[test]
fn the_cli_refuses_without_writing() {
    let dir = tempfile::tempdir().unwrap();
    let tree = robonaut();
    let (dofs, _) = moving(&tree, "left_tool");
    let periodic = Motion::new(&tree, &dofs, 14, true, 5);
    let config = logs(dir.path(), "left_tool", &periodic, &Recording::default());
    let out = dir.path().join("m.csv");
    let args = |extra: &[&str]| {
        let mut args = vec![
            "pair".to_string(),
            "--joints".into(),
            config.joints.display().to_string(),
            "--tracker".into(),
            config.tracker.display().to_string(),
            "--tool".into(),
            "left_tool".into(),
            "--out".into(),
            out.display().to_string(),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        args
    };
    let run = |extra: &[&str]| {
        let owned = args(extra);
        treecal(&owned.iter().map(String::as_str).collect::<Vec<_>>())
    };
    assert_error(
        &run(&[]),
        &["ambiguous", "--clock-offset"],
        "repetitive motion",
    );
    let offset = format!("{}", Recording::default().offset());
    let strict = run(&["--clock-offset", &offset, "--max-marker-spread", "0.001"]);
    assert_error(
        &strict,
        &["no plateau", "spread", "at most 0.001 mm"],
        "strict thresholds",
    );
    assert!(!out.exists() && !dir.path().join("m.pairing.md").exists());
    let run = run(&["--clock-offset", &offset]);
    assert_success(&run, "pair with the offset given");
    // 14 holds, the first seen only in part by the tracker.
    let paired: usize = run
        .stderr
        .split("paired ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!((12..=14).contains(&paired), "{run}");
    assert!(out.exists() && dir.path().join("m.pairing.md").exists());
}
