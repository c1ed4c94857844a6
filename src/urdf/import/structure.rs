//! The URDF's link and joint structure: unique names, one parent per link, one root, no
//! cycle.

// The parent's types and imports.
use super::*;

/// Indices in the file by name.
type NameIndex<'r> = HashMap<&'r str, usize>;

/// Each link's parent joint and child joints (indices in the file).
type ParentsAndChildren = (Vec<Option<usize>>, Vec<Vec<usize>>);

impl<'t> Importer<'t> {
    /// Every link's and joint's index by name, or the first name used twice.
    pub(super) fn unique_names<'r>(
        &self,
        robot: &'r urdf_rs::Robot,
    ) -> Result<(NameIndex<'r>, NameIndex<'r>)> {
        // Names must be unique: everything downstream refers to links and joints by name.
        let mut link_index: HashMap<&str, usize> = HashMap::new();
        for (index, link) in robot.links.iter().enumerate() {
            if link_index.insert(link.name.as_str(), index).is_some() {
                return Err(self.invalid(
                    "link",
                    &link.name,
                    format!(
                        "link name '{}' is used twice; link names must be unique",
                        link.name
                    ),
                ));
            }
        }
        let mut joint_names: HashMap<&str, usize> = HashMap::new();
        for (index, joint) in robot.joints.iter().enumerate() {
            if joint_names.insert(joint.name.as_str(), index).is_some() {
                return Err(self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint name '{}' is used twice; joint names must be unique",
                        joint.name
                    ),
                ));
            }
        }
        Ok((link_index, joint_names))
    }

    /// Each link's parent joint and child joints (indices in the file), or what breaks the
    /// tree: a missing link, a link with two parents.
    pub(super) fn parent_joints(
        &self,
        robot: &urdf_rs::Robot,
        link_index: &HashMap<&str, usize>,
    ) -> Result<ParentsAndChildren> {
        // Parent/child structure: each link at most one parent joint, every named link exists.
        let mut parent_joint_of: Vec<Option<usize>> = vec![None; robot.links.len()];
        let mut children_of: Vec<Vec<usize>> = vec![Vec::new(); robot.links.len()];
        for (index, joint) in robot.joints.iter().enumerate() {
            let parent = *link_index.get(joint.parent.link.as_str()).ok_or_else(|| {
                self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' names parent link '{}', which does not exist{}",
                        joint.name,
                        joint.parent.link,
                        crate::error::did_you_mean(&joint.parent.link, link_index.keys().copied())
                    ),
                )
            })?;
            let child = *link_index.get(joint.child.link.as_str()).ok_or_else(|| {
                self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' names child link '{}', which does not exist{}",
                        joint.name,
                        joint.child.link,
                        crate::error::did_you_mean(&joint.child.link, link_index.keys().copied())
                    ),
                )
            })?;
            if let Some(other) = parent_joint_of[child] {
                return Err(self.invalid(
                "joint",
                &joint.name,
                format!(
                    "link '{}' is the child of both joint '{}' and joint '{}'; a URDF must be a tree",
                    joint.child.link, robot.joints[other].name, joint.name
                ),
            ));
            }
            parent_joint_of[child] = Some(index);
            children_of[parent].push(index);
        }
        Ok((parent_joint_of, children_of))
    }

    /// The one link without a parent joint.
    pub(super) fn root_link(
        &self,
        robot: &urdf_rs::Robot,
        parent_joint_of: &[Option<usize>],
        link_index: &HashMap<&str, usize>,
    ) -> Result<usize> {
        let roots: Vec<usize> = (0..robot.links.len())
            .filter(|&l| parent_joint_of[l].is_none())
            .collect();
        let root = match roots.as_slice() {
            [root] => *root,
            [] => {
                return Err(self.cycle_error(
                    robot,
                    parent_joint_of,
                    link_index,
                    0,
                    "every link has a parent joint, so there is no root link",
                ));
            }
            many => {
                let names: Vec<&str> = many.iter().map(|&l| robot.links[l].name.as_str()).collect();
                return Err(Error::InvalidRobot {
                origin: self.origin.to_owned(),
                message: format!(
                    "the robot has {} root links ({}); connect all but one to the tree with a joint",
                    names.len(),
                    names.join(", ")
                ),
            });
            }
        };
        Ok(root)
    }

    /// The links in breadth-first order from the root, or the cycle that leaves some out.
    pub(super) fn breadth_first(
        &self,
        robot: &urdf_rs::Robot,
        root: usize,
        (parent_joint_of, children_of): (&[Option<usize>], &[Vec<usize>]),
        link_index: &HashMap<&str, usize>,
    ) -> Result<Vec<usize>> {
        // Breadth-first order from the root; links never reached sit on a cycle.
        let mut order = Vec::with_capacity(robot.links.len());
        let mut queue = VecDeque::from([root]);
        while let Some(link) = queue.pop_front() {
            order.push(link);
            for &joint in &children_of[link] {
                queue.push_back(link_index[robot.joints[joint].child.link.as_str()]);
            }
        }
        if order.len() != robot.links.len() {
            let mut seen = vec![false; robot.links.len()];
            for &l in &order {
                seen[l] = true;
            }
            // Walking up the parent joints from any unreached link must end on a cycle.
            let stuck = (0..robot.links.len()).find(|&l| !seen[l]).unwrap_or(0);
            return Err(self.cycle_error(
                robot,
                parent_joint_of,
                link_index,
                stuck,
                &format!(
                    "some links cannot be reached from the root link '{}'",
                    robot.links[root].name
                ),
            ));
        }
        Ok(order)
    }

    /// An error naming the joints of the cycle found by walking parent joints up from link
    /// `start`, located at the first of them in the file.
    pub(super) fn cycle_error(
        &self,
        robot: &urdf_rs::Robot,
        parent_joint_of: &[Option<usize>],
        link_index: &HashMap<&str, usize>,
        start: usize,
        context: &str,
    ) -> Error {
        let mut step_of = vec![None; parent_joint_of.len()];
        let mut walked = Vec::new();
        let mut link = start;
        while step_of[link].is_none() {
            step_of[link] = Some(walked.len());
            let Some(joint) = parent_joint_of[link] else {
                break;
            };
            walked.push(joint);
            link = link_index[robot.joints[joint].parent.link.as_str()];
        }
        // Child → parent order; turn it round and start at the joint written first.
        let mut cycle = walked.split_off(step_of[link].unwrap_or(walked.len()));
        cycle.reverse();
        if let Some(first) = cycle
            .iter()
            .enumerate()
            .min_by_key(|(_, &j)| j)
            .map(|(i, _)| i)
        {
            cycle.rotate_left(first);
        }
        let Some(&first) = cycle.first() else {
            return Error::InvalidRobot {
                origin: self.origin.to_owned(),
                message: format!("{context}; a URDF must be a tree with one root link"),
            };
        };
        let joints: Vec<String> = cycle
            .iter()
            .map(|&j| format!("'{}'", robot.joints[j].name))
            .collect();
        let mut path = vec![robot.joints[first].parent.link.as_str()];
        path.extend(cycle.iter().map(|&j| robot.joints[j].child.link.as_str()));
        self.invalid(
            "joint",
            &robot.joints[first].name,
            format!(
                "{context}: joints {} form a cycle ({}); a URDF must be a tree with one root link",
                joints.join(", "),
                path.join(" → ")
            ),
        )
    }
}
