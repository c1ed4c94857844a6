use super::*;

fn shape(urdf_shape: Shape) -> (SharedShape, ShapePose) {
    let invalid = |what: &str, value: f64| Error::InvalidData {
        origin: what.into(),
        message: value.to_string(),
    };
    match parry_shape(&urdf_shape, &invalid) {
        Ok(Some(found)) => found,
        _ => panic!("no parry shape for {urdf_shape:?}"),
    }
}

/// parry's cylinder, turned by the axis change, lies along the URDF z axis.
#[test]
fn cylinder_axis_becomes_z() {
    let (cylinder, shape_from_parry) = shape(Shape::Cylinder {
        radius: 0.1,
        length: 2.0,
    });
    let aabb = cylinder.compute_aabb(&shape_from_parry);
    assert!((aabb.maxs.z - 1.0).abs() < 1e-12, "{aabb:?}");
    assert!((aabb.maxs.y - 0.1).abs() < 1e-12, "{aabb:?}");
}

/// Every vertex of a box and every rim point of a cylinder lies inside its capsule bound.
#[test]
fn bounding_capsules_contain_their_shapes() {
    let (cuboid, _) = shape(Shape::Box {
        size: crate::math::Vec3::new(0.2, 0.6, 0.1),
    });
    let ([a, b], radius) = bounding_capsule(&cuboid);
    for corner in 0..8 {
        let sign = |bit: usize| if corner & bit == 0 { -1.0 } else { 1.0 };
        let p = ShapeVector::new(0.1 * sign(1), 0.3 * sign(2), 0.05 * sign(4));
        let distance = segment_distance_squared(a, b, p, p).sqrt();
        assert!(distance <= radius + 1e-12, "{p:?}: {distance} > {radius}");
    }
    let (cylinder, _) = shape(Shape::Cylinder {
        radius: 0.1,
        length: 0.5,
    });
    let ([a, b], radius) = bounding_capsule(&cylinder);
    let rim = ShapeVector::new(0.1, 0.25, 0.0);
    assert!(segment_distance_squared(a, b, rim, rim).sqrt() <= radius + 1e-12);
}

#[test]
fn segment_distances() {
    let v = ShapeVector::new;
    // Crossing at right angles, 1 apart in z.
    let d = segment_distance_squared(v(-1., 0., 0.), v(1., 0., 0.), v(0., -1., 1.), v(0., 1., 1.));
    assert!((d - 1.0).abs() < 1e-15);
    // Parallel and overlapping, 0.5 apart.
    let d = segment_distance_squared(v(0., 0., 0.), v(2., 0., 0.), v(1., 0.5, 0.), v(3., 0.5, 0.));
    assert!((d - 0.25).abs() < 1e-15);
    // End to end along a line.
    let d = segment_distance_squared(v(0., 0., 0.), v(1., 0., 0.), v(3., 0., 0.), v(2., 0., 0.));
    assert!((d - 1.0).abs() < 1e-15);
    // A point and a segment.
    let d = segment_distance_squared(v(0., 2., 0.), v(0., 2., 0.), v(-1., 0., 0.), v(1., 0., 0.));
    assert!((d - 4.0).abs() < 1e-15);
}
