//! URDF import: every robot loads; bad files give clear errors.
