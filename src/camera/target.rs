//! What a camera looks at: calibration boards (a grid of corners with a known spacing) and
//! single markers, each with its points in its own frame.

use crate::math::Vec3;

/// The shape of a target: its points in the target frame.
#[derive(Debug, Clone, PartialEq)]
pub enum TargetShape {
    /// A planar grid of `rows` × `columns` corners `spacing` apart (m): corner `k` is at
    /// `(spacing·(k mod columns), spacing·(k div columns), 0)`, OpenCV's object points of a
    /// checkerboard or ChArUco board. The printed face looks along the frame's −z.
    Board {
        /// Corner rows.
        rows: usize,
        /// Corner columns.
        columns: usize,
        /// Distance between neighbouring corners (m).
        spacing: f64,
    },
    /// One point at the target frame's origin (an LED, the centre of a single marker).
    Marker,
}

impl TargetShape {
    /// Number of points.
    pub fn point_count(&self) -> usize {
        match self {
            TargetShape::Board { rows, columns, .. } => rows * columns,
            TargetShape::Marker => 1,
        }
    }

    /// Point `index` in the target frame (m), `None` beyond [`Self::point_count`].
    pub fn point(&self, index: usize) -> Option<Vec3> {
        match *self {
            TargetShape::Board {
                rows,
                columns,
                spacing,
            } => (index < rows * columns).then(|| {
                Vec3::new(
                    spacing * (index % columns) as f64,
                    spacing * (index / columns) as f64,
                    0.0,
                )
            }),
            TargetShape::Marker => (index == 0).then(Vec3::zeros),
        }
    }

    /// Every point, in index order.
    pub fn points(&self) -> Vec<Vec3> {
        (0..self.point_count())
            .filter_map(|k| self.point(k))
            .collect()
    }

    /// The middle of the target (m, target frame): where a camera should look.
    pub fn centre(&self) -> Vec3 {
        match *self {
            TargetShape::Board {
                rows,
                columns,
                spacing,
            } => Vec3::new(
                0.5 * spacing * (columns.max(1) - 1) as f64,
                0.5 * spacing * (rows.max(1) - 1) as f64,
                0.0,
            ),
            TargetShape::Marker => Vec3::zeros(),
        }
    }

    /// Whether the target has a face that can turn away from a camera (boards do).
    pub fn has_face(&self) -> bool {
        matches!(self, TargetShape::Board { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_corners_follow_opencv_order() {
        let board = TargetShape::Board {
            rows: 3,
            columns: 4,
            spacing: 0.03,
        };
        assert_eq!(board.point_count(), 12);
        assert_eq!(board.point(5), Some(Vec3::new(0.03, 0.03, 0.0)));
        assert_eq!(board.point(12), None);
        assert!((board.centre() - Vec3::new(0.045, 0.03, 0.0)).norm() < 1e-15);
        assert_eq!(TargetShape::Marker.points(), vec![Vec3::zeros()]);
    }
}
