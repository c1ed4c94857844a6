//! Where the columns of a measurement CSV go: identity, joints, observation.

// The parent's types, constants and imports.
use super::checks::quoted_list;
use super::*;

/// Where the columns of a measurement CSV go.
pub(super) struct Columns {
    pub(super) id: Option<usize>,
    pub(super) stage: Option<usize>,
    /// `payload_kg`: the payload at every tool for this row (kg).
    pub(super) payload: Option<usize>,
    /// `session`: the measurement session of this row.
    pub(super) session: Option<usize>,
    pub(super) tool: Option<usize>,
    pub(super) point: Option<usize>,
    /// Columns skipped as neither joints nor measurement columns: name, and how to say it.
    pub(super) skipped: Vec<(String, String)>,
    /// `(column, dof)` of independent joints.
    pub(super) joints: Vec<(usize, usize)>,
    pub(super) observation: ObservationKind,
    /// The observation columns in [`ObservationKind::columns`] order.
    pub(super) observed: Vec<usize>,
}

/// Sorts the header's columns into identity, joints and observation, or says which is wrong.
/// Columns that are neither (and not listed as ignored) are skipped, named in
/// [`Columns::skipped`].
pub(super) fn classify(
    headers: &[String],
    header_line: usize,
    places: Places,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
    origin: &str,
) -> Result<Columns> {
    // A header of one field holding semicolons or tabs (another separator) was refused when
    // the table was read (`joints_csv::check_separator`, the only such check).
    let mut id = None;
    let mut stage = None;
    let mut payload = None;
    let mut session = None;
    let mut tool = None;
    let mut point = None;
    let mut joints = Vec::new();
    let mut skipped = Vec::new();
    let mut observed: HashMap<&str, usize> = HashMap::new();
    for (column, name) in headers.iter().enumerate() {
        if options.ignore_columns.contains(name) {
            continue;
        }
        match name.as_str() {
            "id" => id = Some(column),
            "stage" => stage = Some(column),
            PAYLOAD_COLUMN => payload = Some(column),
            SESSION_COLUMN => session = Some(column),
            "tool" => tool = Some(column),
            POINT_COLUMN => point = Some(column),
            other if OBSERVATION_COLUMNS.contains(&other) => {
                observed.insert(other, column);
            }
            other => match tree.joint_id(other).map(|j| tree.joint(j).actuation) {
                Ok(Actuation::Independent(dof)) => joints.push((column, dof.0)),
                Ok(Actuation::Mimic { master, .. }) => skipped.push((
                    other.to_owned(),
                    format!(
                        "'{other}' (a mimic joint: its value follows '{}')",
                        tree.joint(tree.dofs()[master.0]).name
                    ),
                )),
                Ok(Actuation::None) => {
                    skipped.push((other.to_owned(), format!("'{other}' (a fixed joint)")))
                }
                Err(_) => {
                    let candidates = tree
                        .dofs()
                        .iter()
                        .map(|j| tree.joint(*j).name.as_str())
                        .chain(OBSERVATION_COLUMNS)
                        .chain(IDENTITY)
                        .chain([PAYLOAD_COLUMN, SESSION_COLUMN]);
                    let hint = did_you_mean(other, candidates);
                    skipped.push((
                        other.to_owned(),
                        format!("'{}'{hint}", crate::limits::cut(other)),
                    ));
                }
            },
        }
    }
    if tool.is_none() && options.tool.is_none() && model.tools().len() != 1 {
        let names: Vec<&str> = model
            .tools()
            .iter()
            .map(|t| tree.link(t.link).name.as_str())
            .collect();
        return Err(Error::InvalidData {
            origin: places.header(origin, header_line, None),
            message: format!(
                "the header has no 'tool' column; add one naming the measured tool link of each \
                 row (one of {}), or name the one measured tool with `tools`",
                quoted_list(&names)
            ),
        });
    }
    let observation = layout(&observed, places.header(origin, header_line, None))?;
    let observed = observation.columns().iter().map(|c| observed[c]).collect();
    Ok(Columns {
        id,
        stage,
        payload,
        session,
        tool,
        point,
        skipped,
        joints,
        observation,
        observed,
    })
}

/// The observation layout whose columns the header has, exactly; `header` names the header
/// row in messages.
fn layout(observed: &HashMap<&str, usize>, header: String) -> Result<ObservationKind> {
    KINDS
        .into_iter()
        .find(|kind| {
            kind.columns().len() == observed.len()
                && kind.columns().iter().all(|c| observed.contains_key(c))
        })
        .ok_or_else(|| {
            let mut present: Vec<(&str, usize)> =
                observed.iter().map(|(n, c)| (*n, *c)).collect();
            present.sort_by_key(|(_, c)| *c);
            let present: Vec<&str> = present.into_iter().map(|(n, _)| n).collect();
            Error::InvalidData {
                origin: header,
                message: if present.is_empty() {
                    format!("the header has no observation columns; give {LAYOUTS}")
                } else {
                    format!(
                        "the observation columns {} are not a complete layout; give exactly {LAYOUTS}",
                        present.join(",")
                    )
                },
            }
        })
}
