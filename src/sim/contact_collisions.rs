//! Contact configurations free of self-collision (issue 29: "the hands really meet within
//! joint limits and without other self-collision"). A generated contact configuration is kept
//! only when the robot's `<collision>` shapes ([`CollisionChecker`], as `simulate` and `plan`
//! check tracker configurations) collide nowhere but where the contact itself touches: for a
//! `touch`, the two hands — each tool's last moving link and every link it carries — may
//! meet; a flush face, a plane point and a bar's ends touch nothing of the robot, so every
//! pair counts there. With a reference link (a sole), pairs within the support leg (the links
//! from it to the root) are not checked: the generator moves that leg freely to reach the
//! table, where a lab's standing robot holds it in its balance controller's posture (Atlas's
//! coarse ankle boxes then collide in nearly every generated configuration).

use super::collision::CollisionChecker;
use crate::measurement::Contact;
use crate::tree::{KinematicTree, LinkId};
use crate::McpcModel;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// The self-collision check of contact configurations (cheap to clone: shared).
#[derive(Clone)]
pub struct ContactCollisions {
    tree: Arc<KinematicTree>,
    checker: Arc<CollisionChecker>,
    /// Per tool of the model: the links of its hand (see the module documentation).
    hands: Arc<Vec<Vec<LinkId>>>,
    /// The links from the reference link (a sole) to the root: the support leg.
    support: Arc<Vec<LinkId>>,
    /// Projected configurations rejected for self-collision so far.
    rejected: Arc<AtomicUsize>,
}

impl std::fmt::Debug for ContactCollisions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ContactCollisions")
            .field("pairs", &self.checker.pair_count())
            .field("rejected", &self.rejected())
            .finish()
    }
}

impl ContactCollisions {
    /// The check of `tree` with `checker`, the hands those of `model`'s tools.
    pub fn new(tree: &KinematicTree, model: &McpcModel, checker: CollisionChecker) -> Self {
        let hands = model
            .tools()
            .iter()
            .map(|tool| hand(tree, tool.link))
            .collect();
        let support = model.reference().map_or_else(Vec::new, |r| {
            (0..tree.links().len())
                .map(LinkId)
                .filter(|&l| tree.is_ancestor(l, r.link))
                .collect()
        });
        Self {
            tree: Arc::new(tree.clone()),
            checker: Arc::new(checker),
            hands: Arc::new(hands),
            support: Arc::new(support),
            rejected: Arc::new(AtomicUsize::new(0)),
        }
    }

    /// Whether `q` is free of self-collision but for what `contact` of `tool` touches (`None`:
    /// no contact, every pair but the support leg's counts); counts a rejection.
    pub fn allows(&self, contact: Option<&Contact>, tool: usize, q: &[f64]) -> bool {
        let free = self.free(contact, tool, q);
        if !free {
            self.rejected.fetch_add(1, Ordering::Relaxed);
        }
        free
    }

    fn free(&self, contact: Option<&Contact>, tool: usize, q: &[f64]) -> bool {
        let Ok(poses) = self.tree.link_poses(q) else {
            return false;
        };
        if !self.checker.in_collision(&poses) {
            return true;
        }
        let support = |x: &LinkId, y: &LinkId| self.support.contains(x) && self.support.contains(y);
        let hands = match contact {
            Some(Contact::Touch { tool2, .. }) => self.hands.get(tool).zip(self.hands.get(*tool2)),
            _ => None,
        };
        self.checker.colliding_pairs(&poses).iter().all(|(x, y)| {
            support(x, y)
                || hands.is_some_and(|(a, b)| {
                    (a.contains(x) && b.contains(y)) || (a.contains(y) && b.contains(x))
                })
        })
    }

    /// Projected configurations rejected for self-collision so far.
    pub fn rejected(&self) -> usize {
        self.rejected.load(Ordering::Relaxed)
    }

    /// Link pairs the check tests.
    pub fn pair_count(&self) -> usize {
        self.checker.pair_count()
    }
}

/// The hand of the tool at `link`: its moving body (the link reached from `link` up through
/// fixed joints, `link` itself when a movable joint carries it), every link below that body,
/// and the link its joint hangs from (a wrist).
fn hand(tree: &KinematicTree, link: LinkId) -> Vec<LinkId> {
    let mut body = link;
    while let Some(joint) = tree.link(body).parent_joint {
        if tree.joint(joint).kind.is_movable() {
            break;
        }
        body = tree.joint(joint).parent;
    }
    let carrier = tree.link(body).parent_joint.map(|j| tree.joint(j).parent);
    (0..tree.links().len())
        .map(LinkId)
        .filter(|&l| tree.is_ancestor(body, l) || Some(l) == carrier)
        .collect()
}
