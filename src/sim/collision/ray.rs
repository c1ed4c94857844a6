//! Lines of sight through the robot's collision shapes: whether the segment from a camera's
//! centre to a target point crosses a link's collision shape (`plan --camera`, docs/camera.md).

use super::{CollisionChecker, ShapePose, ShapeVector};
use crate::math::{Pose, Vec3};
use crate::tree::LinkId;
use parry3d_f64::query::Ray;

impl CollisionChecker {
    /// The first link (in the checker's order) whose collision shape the segment `from → to`
    /// (root frame, m) crosses, with the link poses of one configuration; links in `ignore`
    /// (the camera's own link, the target's link) are skipped. The segment's last `end_margin`
    /// (m) is not checked, so a point on a link's surface does not hide itself. `None`: the
    /// line of sight is clear.
    ///
    /// # Panics
    ///
    /// As [`Self::in_collision`].
    pub fn segment_blocked(
        &self,
        link_poses: &[Pose],
        from: &Vec3,
        to: &Vec3,
        ignore: &[LinkId],
        end_margin: f64,
    ) -> Option<LinkId> {
        let length = (to - from).norm();
        if !length.is_finite() || length <= end_margin {
            return None;
        }
        let direction = (to - from) / length;
        let origin = ShapeVector::new(from.x, from.y, from.z);
        let ray = Ray::new(
            origin,
            ShapeVector::new(direction.x, direction.y, direction.z),
        );
        let reach = length - end_margin;
        let placed = self.place(link_poses);
        for (link, (root_from_link, center)) in self.links.iter().zip(&placed) {
            if ignore.contains(&link.link) {
                continue;
            }
            // The bounding sphere first: the segment's closest point to its centre.
            let along = (*center - origin).dot(ray.dir).clamp(0.0, reach);
            if (origin + ray.dir * along).distance(*center) > link.radius {
                continue;
            }
            let hit = link.shapes.iter().any(|shape| {
                let root_from_shape: ShapePose = *root_from_link * shape.link_from_shape;
                shape
                    .shape
                    .cast_ray(&root_from_shape, &ray, reach, true)
                    .is_some()
            });
            if hit {
                return Some(link.link);
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit box on the root link, 1 m along x: a segment through it is blocked, one beside it
    /// is not, and one ending on its surface (within the margin) is not.
    #[test]
    fn a_segment_through_a_box_is_blocked() {
        let urdf = r#"<robot name="r">
  <link name="base"><collision><origin xyz="1 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="tip"/>
  <joint name="j" type="revolute"><parent link="base"/><child link="tip"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"#;
        let tree = crate::urdf::parse_urdf(urdf, "test").unwrap().tree;
        let checker = CollisionChecker::new(&tree).unwrap();
        let poses = tree.link_poses(&tree.zero_configuration()).unwrap();
        let from = Vec3::new(0.0, 0.0, 0.0);
        let base = tree.link_id("base").unwrap();
        let blocked = checker.segment_blocked(&poses, &from, &Vec3::new(2.0, 0.0, 0.0), &[], 0.0);
        assert_eq!(blocked, Some(base));
        let beside = Vec3::new(2.0, 0.5, 0.0);
        assert_eq!(
            checker.segment_blocked(&poses, &from, &beside, &[], 0.0),
            None
        );
        let surface = Vec3::new(0.9, 0.0, 0.0);
        assert_eq!(
            checker.segment_blocked(&poses, &from, &surface, &[], 1e-3),
            None
        );
        let ignored =
            checker.segment_blocked(&poses, &from, &Vec3::new(2.0, 0.0, 0.0), &[base], 0.0);
        assert_eq!(ignored, None);
    }
}
