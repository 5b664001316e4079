//! Kinematics: each process maps the machine's motion to tool poses in the workpiece frame.

pub mod pose_table;
pub mod turning;

pub use pose_table::{PoseTable, ToolPose};
pub use turning::{FeedAlong, TurningMode, TurningSpiral};
