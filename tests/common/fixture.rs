//! The set-up most tests start from: a URDF loaded, its branches detected (or built on the tool
//! links named, as `--tools` does) and the nominal MCPC model of those branches.

use std::path::Path;
use treecal::tree::{Branches, KinematicTree};
use treecal::McpcModel;

/// A robot as the tests use it: the tree, its branches and the nominal model.
pub struct TestRobot {
    pub tree: KinematicTree,
    pub branches: Branches,
    pub model: McpcModel,
}

impl TestRobot {
    /// `tree` with its detected branches, or with the named tool links.
    pub fn from_tree(tree: KinematicTree, tools: Option<&[&str]>) -> Self {
        let branches = super::branches_with_tools(&tree, tools);
        let model = McpcModel::from_tree(&tree, &branches).unwrap_or_else(|e| panic!("{e}"));
        Self {
            tree,
            branches,
            model,
        }
    }

    /// The URDF at `path`.
    pub fn load(path: &Path) -> Self {
        let tree = treecal::load_urdf(path)
            .unwrap_or_else(|e| panic!("{e}"))
            .tree;
        Self::from_tree(tree, None)
    }

    /// The URDF `robots/<relative>` of the repository.
    pub fn repo(relative: &str) -> Self {
        Self::load(&super::robot(relative))
    }

    /// A URDF given as text.
    pub fn parse(text: &str) -> Self {
        let tree = treecal::parse_urdf(text, "robot")
            .unwrap_or_else(|e| panic!("{e}"))
            .tree;
        Self::from_tree(tree, None)
    }

    /// The built-in Robonaut (`robots/robonaut/robonaut.urdf`).
    pub fn robonaut() -> Self {
        Self::repo("robonaut/robonaut.urdf")
    }

    /// The tree, the branches and the model.
    pub fn parts(self) -> (KinematicTree, Branches, McpcModel) {
        (self.tree, self.branches, self.model)
    }

    /// The tree and the model (most tests need no more).
    pub fn tree_and_model(self) -> (KinematicTree, McpcModel) {
        (self.tree, self.model)
    }
}

/// The tree and nominal model of `robots/<relative>`.
pub fn robot_model(relative: &str) -> (KinematicTree, McpcModel) {
    TestRobot::repo(relative).tree_and_model()
}

/// The tree and nominal model of the built-in Robonaut.
pub fn robonaut_model() -> (KinematicTree, McpcModel) {
    TestRobot::robonaut().tree_and_model()
}
