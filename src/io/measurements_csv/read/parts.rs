//! A [`SetBuilder`] fed by blocks read in parallel (`super::super::blocks`): each block's rows
//! are read into a [`Part`] as [`SetBuilder::push`] reads them, and the parts are merged in
//! file order. What depends on earlier rows (unique ids, repeated rows, row numbers as ids)
//! is settled in the merge.

use super::super::blocks::BlockRows;
use super::*;
use std::hash::{Hash, Hasher};

/// The rows of one block.
pub(in crate::io::measurements_csv) struct Part {
    measurements: Vec<Measurement>,
    ids: Vec<String>,
    lines: Vec<usize>,
    /// Each row's [`Repeats::fingerprint`].
    fingerprints: Vec<(u64, u64)>,
    /// Each row's id digest (none without an id column: row numbers are unique).
    id_digests: Vec<u64>,
    tally: Tally,
}

impl BlockRows for SetBuilder<'_> {
    type Part = Part;

    fn part(&self) -> Part {
        Part {
            measurements: Vec::new(),
            ids: Vec::new(),
            lines: Vec::new(),
            fingerprints: Vec::new(),
            id_digests: Vec::new(),
            tally: Tally {
                outside: Vec::new(),
                revolute_values: 0,
                first_line_of_id: None,
                repeats: Repeats::new(None),
                position_rows: Vec::new(),
            },
        }
    }

    fn row(&self, part: &mut Part, row: CsvRow<'_>) -> Option<()> {
        // The index only names rows without an id column; the merge numbers those.
        let index = part.lines.len();
        let (id, measurement) = self.reader.read_row(index, row, &mut part.tally).ok()?;
        if self.reader.columns.id.is_some() {
            let mut digest = crate::digests::digest_hasher(0);
            id.hash(&mut digest);
            part.id_digests.push(digest.finish());
        }
        part.fingerprints.push(self.tally.repeats.fingerprint(row));
        part.measurements.push(measurement);
        part.ids.push(id);
        part.lines.push(row.line);
        Some(())
    }

    /// Adds the part's rows; their ids and repeats are checked at the [`Self::end`].
    fn merge(&mut self, part: Part) -> Option<()> {
        self.id_digests.extend(part.id_digests);
        let first_index = self.set.lines.len();
        let mut ids = part.ids;
        if self.reader.columns.id.is_none() {
            for (k, id) in ids.iter_mut().enumerate() {
                *id = (first_index + k + 1).to_string();
            }
        }
        self.tally.repeats.defer(&part.fingerprints, &part.lines);
        let tally = part.tally;
        self.tally.outside.extend(tally.outside);
        self.tally.revolute_values += tally.revolute_values;
        self.tally.position_rows.extend(tally.position_rows);
        self.set.measurements.extend(part.measurements);
        self.set.ids.extend(ids);
        self.set.lines.extend(part.lines);
        Some(())
    }

    /// `None` when an id repeats an earlier row's, or its digest does (the sequential reader
    /// then names the row, or reads the file when two ids only share a digest); the repeated
    /// rows found. Both by parallel sorts of the digests, not hash tables filled row by row.
    fn end(&mut self) -> Option<()> {
        use rayon::slice::ParallelSliceMut;
        self.id_digests.par_sort_unstable();
        if self.id_digests.windows(2).any(|pair| pair[0] == pair[1]) {
            return None;
        }
        self.id_digests = Vec::new();
        self.tally.repeats.settle();
        Some(())
    }
}
