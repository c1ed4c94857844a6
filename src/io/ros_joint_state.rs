//! `sensor_msgs/msg/JointState` messages as ROS 2 serialises them (CDR, little- or
//! big-endian): the header stamp, the joint names and their positions; velocity and effort
//! are not read. Every length is checked against the bytes left, so a damaged message is an
//! error, never a panic or a huge allocation.

/// The part of a JointState message treecal uses.
#[derive(Debug, Clone, PartialEq)]
pub struct JointStateMessage {
    /// `header.stamp` in seconds (`sec + nanosec·1e-9`).
    pub stamp: f64,
    /// `name[]`.
    pub names: Vec<String>,
    /// `position[]` (rad, or m for prismatic joints), one per name.
    pub positions: Vec<f64>,
}

/// Decodes a CDR-encoded JointState (with its 4-byte encapsulation header). The error says
/// what is wrong, without a place (the caller names the message).
pub fn decode_joint_state(data: &[u8]) -> Result<JointStateMessage, String> {
    let little = match data.get(..2) {
        Some([0, 1]) => true,
        Some([0, 0]) => false,
        Some(kind) => {
            return Err(format!(
            "unsupported CDR encapsulation {:#04x}{:02x} (plain CDR, 0x0000 or 0x0001, expected)",
            kind[0], kind[1]
        ))
        }
        None => return Err("shorter than the CDR encapsulation header".into()),
    };
    let mut cdr = Cdr {
        data,
        at: 4,
        little,
    };
    if data.len() < 4 {
        return Err("shorter than the CDR encapsulation header".into());
    }
    let sec = cdr.u32()? as i32;
    let nanosec = cdr.u32()?;
    let _frame_id = cdr.string()?;
    let count = cdr.count(5)?;
    let mut names = Vec::with_capacity(count);
    for _ in 0..count {
        names.push(cdr.string()?);
    }
    let count = cdr.count(8)?;
    let mut positions = Vec::with_capacity(count);
    for _ in 0..count {
        positions.push(cdr.f64()?);
    }
    if positions.len() != names.len() {
        return Err(format!(
            "{} names but {} positions; a joint log needs a position for every name",
            names.len(),
            positions.len()
        ));
    }
    Ok(JointStateMessage {
        stamp: f64::from(sec) + f64::from(nanosec) * 1e-9,
        names,
        positions,
    })
}

/// A cursor over CDR data; alignment counts from the end of the encapsulation header.
struct Cdr<'a> {
    data: &'a [u8],
    at: usize,
    little: bool,
}

impl<'a> Cdr<'a> {
    fn take(&mut self, size: usize) -> Result<&'a [u8], String> {
        let aligned = 4 + (self.at - 4).div_ceil(size) * size;
        let end = aligned.checked_add(size).filter(|&e| e <= self.data.len());
        let end = end.ok_or_else(|| format!("truncated: ends at byte {}", self.data.len()))?;
        self.at = end;
        Ok(&self.data[aligned..end])
    }

    fn u32(&mut self) -> Result<u32, String> {
        let bytes: [u8; 4] = self
            .take(4)?
            .try_into()
            .map_err(|_| "truncated".to_string())?;
        Ok(if self.little {
            u32::from_le_bytes(bytes)
        } else {
            u32::from_be_bytes(bytes)
        })
    }

    fn f64(&mut self) -> Result<f64, String> {
        let bytes: [u8; 8] = self
            .take(8)?
            .try_into()
            .map_err(|_| "truncated".to_string())?;
        Ok(if self.little {
            f64::from_le_bytes(bytes)
        } else {
            f64::from_be_bytes(bytes)
        })
    }

    /// A sequence length whose elements take at least `least` bytes each.
    fn count(&mut self, least: usize) -> Result<usize, String> {
        let count = self.u32()? as usize;
        let left = self.data.len().saturating_sub(self.at);
        if count.saturating_mul(least) > left {
            return Err(format!(
                "a sequence of {count} elements does not fit in the {left} bytes left"
            ));
        }
        Ok(count)
    }

    /// A string: length (with the terminating NUL), bytes, NUL.
    fn string(&mut self) -> Result<String, String> {
        let length = self.u32()? as usize;
        let end = self
            .at
            .checked_add(length)
            .filter(|&e| e <= self.data.len());
        let end = end.ok_or_else(|| format!("a string of {length} bytes does not fit"))?;
        let bytes = &self.data[self.at..end];
        self.at = end;
        let text = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(text.to_vec()).map_err(|_| "a joint name is not UTF-8".to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A little-endian JointState as rclcpp writes it.
    fn message(names: &[&str], positions: &[f64]) -> Vec<u8> {
        let mut out = vec![0, 1, 0, 0];
        let align = |out: &mut Vec<u8>, n: usize| {
            while (out.len() - 4) % n != 0 {
                out.push(0);
            }
        };
        let string = |out: &mut Vec<u8>, s: &str| {
            align(out, 4);
            out.extend((s.len() as u32 + 1).to_le_bytes());
            out.extend(s.as_bytes());
            out.push(0);
        };
        out.extend(12i32.to_le_bytes());
        out.extend(500_000_000u32.to_le_bytes());
        string(&mut out, "base");
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

    #[test]
    fn a_message_reads_back() {
        let data = message(&["a", "joint_b"], &[0.25, -1.5]);
        let m = decode_joint_state(&data).unwrap();
        assert_eq!(m.stamp, 12.5);
        assert_eq!(m.names, ["a", "joint_b"]);
        assert_eq!(m.positions, [0.25, -1.5]);
    }

    #[test]
    fn every_truncation_and_bad_length_is_an_error() {
        let data = message(&["a", "joint_b"], &[0.25, -1.5]);
        for end in 0..data.len() - 8 {
            assert!(decode_joint_state(&data[..end]).is_err(), "{end}");
        }
        let mut huge = data.clone();
        huge[24..28].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode_joint_state(&huge).is_err());
        let mismatch = message(&["a", "b"], &[1.0]);
        assert!(decode_joint_state(&mismatch)
            .unwrap_err()
            .contains("2 names but 1"));
        assert!(decode_joint_state(&[0, 9, 0, 0, 1, 2, 3, 4])
            .unwrap_err()
            .contains("encapsulation"));
    }

    #[test]
    fn mutated_messages_never_panic() {
        let data = message(&["a", "joint_b", "c"], &[0.25, -1.5, 3.0]);
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as usize
        };
        for _ in 0..5000 {
            let mut bad = data.clone();
            for _ in 0..1 + next() % 4 {
                let at = next() % bad.len();
                bad[at] = next() as u8;
            }
            let end = bad.len() - next() % 8;
            let _ = decode_joint_state(&bad[..end]);
        }
    }
}
