//! The flat parameter vector of an MCPC model: its layout, names, values and their update.

// The model's fields and types, and the imports of `mcpc.rs`.
use super::*;

impl McpcModel {
    /// Number of MCPC parameters: 4 per revolute frame, 2 per prismatic frame, 6 per tool.
    pub fn parameter_count(&self) -> usize {
        self.frames
            .iter()
            .map(|f| f.kind.parameter_count())
            .sum::<usize>()
            + 6 * self.tools.len()
            + self
                .joint_errors
                .slots
                .iter()
                .flatten()
                .filter(|v| v.is_some())
                .count()
            + if self.frame_parameters.is_some() {
                6
            } else {
                0
            }
    }

    /// What each entry of the flat parameter vector is: frames in order, then tools.
    pub fn parameter_layout(&self) -> Vec<(ParameterOwner, ParameterKind)> {
        let mut layout = Vec::with_capacity(self.parameter_count());
        for (index, frame) in self.frames.iter().enumerate() {
            let kinds: &[ParameterKind] = match frame.kind {
                FrameKind::Revolute => &REVOLUTE_PARAMETERS,
                FrameKind::Prismatic => &PRISMATIC_PARAMETERS,
            };
            layout.extend(kinds.iter().map(|k| (ParameterOwner::Frame(index), *k)));
        }
        for index in 0..self.tools.len() {
            layout.extend(
                TOOL_PARAMETERS
                    .iter()
                    .map(|k| (ParameterOwner::Tool(index), *k)),
            );
        }
        for (index, slot) in self.joint_errors.slots.iter().enumerate() {
            for (value, kind) in slot
                .iter()
                .zip(super::super::joint_errors::JOINT_ERROR_KINDS)
            {
                if value.is_some() {
                    layout.push((ParameterOwner::Frame(index), kind));
                }
            }
        }
        if self.frame_parameters.is_some() {
            layout.extend(
                TOOL_PARAMETERS
                    .iter()
                    .map(|k| (ParameterOwner::Measurement, *k)),
            );
        }
        layout
    }

    /// Entry `index` of [`Self::parameter_layout`], without building the layout (the finite
    /// differences of the deflections set a parameter twice per column).
    fn parameter_entry(&self, index: usize) -> Option<(ParameterOwner, ParameterKind)> {
        let mut index = index;
        for (frame_index, frame) in self.frames.iter().enumerate() {
            let kinds: &[ParameterKind] = match frame.kind {
                FrameKind::Revolute => &REVOLUTE_PARAMETERS,
                FrameKind::Prismatic => &PRISMATIC_PARAMETERS,
            };
            match kinds.get(index) {
                Some(kind) => return Some((ParameterOwner::Frame(frame_index), *kind)),
                None => index -= kinds.len(),
            }
        }
        let tool_parameters = TOOL_PARAMETERS.len() * self.tools.len();
        if index < tool_parameters {
            let (tool, kind) = (index / TOOL_PARAMETERS.len(), index % TOOL_PARAMETERS.len());
            return Some((ParameterOwner::Tool(tool), TOOL_PARAMETERS[kind]));
        }
        index -= tool_parameters;
        for (frame_index, slot) in self.joint_errors.slots.iter().enumerate() {
            for (value, kind) in slot
                .iter()
                .zip(super::super::joint_errors::JOINT_ERROR_KINDS)
            {
                if value.is_some() {
                    if index == 0 {
                        return Some((ParameterOwner::Frame(frame_index), kind));
                    }
                    index -= 1;
                }
            }
        }
        self.frame_parameters
            .as_ref()
            .and_then(|_| TOOL_PARAMETERS.get(index))
            .map(|kind| (ParameterOwner::Measurement, *kind))
    }

    /// A readable name of parameter `index`, e.g. `left_joint1 alpha` or `left_tool z`.
    pub fn parameter_name(&self, tree: &KinematicTree, index: usize) -> String {
        match self.parameter_layout().get(index) {
            Some((ParameterOwner::Frame(f), kind)) => {
                format!("{} {}", tree.joint(self.frames[*f].joint).name, kind.name())
            }
            Some((ParameterOwner::Tool(t), kind)) => {
                format!("{} {}", tree.link(self.tools[*t].link).name, kind.name())
            }
            Some((ParameterOwner::Measurement, kind)) => {
                format!("measurement_frame {}", kind.name())
            }
            None => format!("parameter {index}"),
        }
    }

    /// The flat parameter vector (rad, m) in [`Self::parameter_layout`] order.
    pub fn parameters(&self) -> Vec<f64> {
        self.parameter_layout()
            .into_iter()
            .map(|(owner, kind)| self.parameter(owner, kind))
            .collect()
    }

    /// One parameter's value.
    pub fn parameter(&self, owner: ParameterOwner, kind: ParameterKind) -> f64 {
        match owner {
            ParameterOwner::Frame(i) => {
                let f = &self.frames[i];
                match kind {
                    ParameterKind::Alpha => f.alpha,
                    ParameterKind::Beta => f.beta,
                    ParameterKind::X => f.x,
                    ParameterKind::Y => f.y,
                    ParameterKind::Gamma | ParameterKind::Z => 0.0,
                    kind => self
                        .joint_error_values(i)
                        .get(joint_error_slot(kind))
                        .copied()
                        .flatten()
                        .unwrap_or(0.0),
                }
            }
            ParameterOwner::Tool(i) => {
                let t = &self.tools[i];
                match kind {
                    ParameterKind::Alpha => t.alpha,
                    ParameterKind::Beta => t.beta,
                    ParameterKind::Gamma => t.gamma,
                    ParameterKind::X => t.x,
                    ParameterKind::Y => t.y,
                    ParameterKind::Z => t.z,
                    _ => 0.0,
                }
            }
            ParameterOwner::Measurement => self
                .frame_parameters
                .as_ref()
                .map_or(0.0, |f| f.values[frame_slot(kind)]),
        }
    }

    /// Replaces every parameter (same order as [`Self::parameters`]).
    pub fn set_parameters(&mut self, values: &[f64]) -> Result<()> {
        let layout = self.parameter_layout();
        if values.len() != layout.len() {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!(
                    "{} values given, the model has {} parameters",
                    values.len(),
                    layout.len()
                ),
            });
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!("parameter {bad} is not finite"),
            });
        }
        for ((owner, kind), value) in layout.into_iter().zip(values) {
            *self.slot(owner, kind) = *value;
        }
        self.refresh();
        self.refresh_world();
        Ok(())
    }

    /// Replaces parameter `index` alone, refreshing only its frame or tool: the cheap way to
    /// perturb one parameter (finite differences).
    pub fn set_parameter(&mut self, index: usize, value: f64) -> Result<()> {
        let Some((owner, kind)) = self.parameter_entry(index) else {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!(
                    "parameter {index} does not exist; the model has {} parameters",
                    self.parameter_count()
                ),
            });
        };
        if !value.is_finite() {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!("parameter {index} is not finite"),
            });
        }
        *self.slot(owner, kind) = value;
        match owner {
            ParameterOwner::Frame(i) => {
                let (axes, constant) = Self::frame_caches(&self.frames[i]);
                self.frame_axes[i] = axes;
                self.frame_constants[i] = constant;
            }
            ParameterOwner::Tool(i) => {
                let (axes, constant) = Self::tool_caches(&self.tools[i]);
                self.tool_axes[i] = axes;
                self.tool_constants[i] = constant;
            }
            ParameterOwner::Measurement => self.refresh_world(),
        }
        Ok(())
    }

    /// [`Self::world_from_base`] from the measurement-frame parameters, if they exist.
    fn refresh_world(&mut self) {
        if let Some(parameters) = &self.frame_parameters {
            self.world_from_base = parameters.effective();
        }
    }

    /// Folds joint offset `delta` of revolute frame `frame` into the constants after it
    /// ([`Self::with_offsets_absorbed`]).
    pub(crate) fn absorb_offset(&mut self, frame: usize, delta: f64) {
        if self.frames[frame].kind != FrameKind::Revolute {
            return;
        }
        for child in self.frames.iter_mut().filter(|f| f.parent == Some(frame)) {
            child.phi += delta;
        }
        for tool in self.tools.iter_mut().filter(|t| t.parent == Some(frame)) {
            tool.phi += delta;
        }
        let link = self.frames[frame].frame_from_link;
        self.frames[frame].frame_from_link = pose(Vec3::zeros(), rot_z(delta)) * link;
        if let Some(slot) = self.joint_errors.slots.get_mut(frame) {
            slot[0] = slot[0].map(|_| 0.0);
        }
        self.refresh();
    }

    /// The field holding parameter `kind` of `owner`.
    fn slot(&mut self, owner: ParameterOwner, kind: ParameterKind) -> &mut f64 {
        match owner {
            ParameterOwner::Frame(i) => {
                let f = &mut self.frames[i];
                match kind {
                    ParameterKind::Alpha => &mut f.alpha,
                    ParameterKind::Beta => &mut f.beta,
                    ParameterKind::X => &mut f.x,
                    ParameterKind::Y | ParameterKind::Gamma | ParameterKind::Z => &mut f.y,
                    kind => {
                        let slots = &mut self.joint_errors.slots;
                        if slots.len() <= i {
                            slots.resize(i + 1, [None; 4]);
                        }
                        slots[i][joint_error_slot(kind)].get_or_insert(0.0)
                    }
                }
            }
            ParameterOwner::Measurement => {
                let reference = self.world_from_base;
                let parameters = self.frame_parameters.get_or_insert(
                    super::super::model_extras::FrameParameters {
                        values: [0.0; 6],
                        reference,
                    },
                );
                &mut parameters.values[frame_slot(kind)]
            }
            ParameterOwner::Tool(i) => {
                let t = &mut self.tools[i];
                match kind {
                    ParameterKind::Alpha => &mut t.alpha,
                    ParameterKind::Beta => &mut t.beta,
                    ParameterKind::Gamma => &mut t.gamma,
                    ParameterKind::X => &mut t.x,
                    ParameterKind::Y => &mut t.y,
                    ParameterKind::Z => &mut t.z,
                    _ => &mut t.gamma,
                }
            }
        }
    }
}

/// The index of a joint-error kind in [`super::super::joint_errors::JOINT_ERROR_KINDS`].
fn joint_error_slot(kind: ParameterKind) -> usize {
    match kind {
        ParameterKind::Offset => 0,
        ParameterKind::Sine => 1,
        ParameterKind::Cosine => 2,
        _ => 3,
    }
}

/// The index of a measurement-frame parameter (α, β, γ, x, y, z).
fn frame_slot(kind: ParameterKind) -> usize {
    match kind {
        ParameterKind::Alpha => 0,
        ParameterKind::Beta => 1,
        ParameterKind::Gamma => 2,
        ParameterKind::X => 3,
        ParameterKind::Y => 4,
        _ => 5,
    }
}
