//! Status codes of plan replies. The numbers are part of the protocol and never change.

/// Outcome of a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Status {
    /// Solved; the path follows.
    Ok = 0,
    /// The start configuration is outside the joint limits.
    InvalidStart = 1,
    /// The start configuration collides.
    StartInCollision = 2,
    /// A goal configuration is outside the joint limits.
    InvalidGoal = 3,
    /// Every goal configuration collides.
    GoalInCollision = 4,
    /// No collision-free IK solution for the pose goal.
    UnreachablePose = 5,
    /// No path within the time limit.
    Timeout = 6,
    /// A configuration has the wrong number of joints.
    WrongDof = 7,
    /// A number is NaN or infinite.
    NotFinite = 8,
    /// The request was written for another protocol version.
    VersionMismatch = 9,
    /// The request is malformed (sizes, counts, unknown method or goal kind).
    BadRequest = 10,
    /// The goal names a link the robot does not have.
    UnknownLink = 11,
    /// The daemon failed internally; the request may be retried.
    Internal = 12,
    /// The plan was cancelled before it finished (the daemon is stopping).
    Cancelled = 13,
    /// An input names an object the world does not hold (removal, attach by id).
    UnknownObject = 14,
    /// An attach names an object the robot already holds (or a report moves a held one).
    AlreadyAttached = 15,
    /// A detach names an object the robot does not hold.
    NotAttached = 16,
    /// An attached object would touch the robot at the current joint state.
    AttachCollides = 17,
}

impl Status {
    /// The status with code `code`, if any.
    pub fn from_code(code: u32) -> Option<Status> {
        use Status::*;
        [
            Ok,
            InvalidStart,
            StartInCollision,
            InvalidGoal,
            GoalInCollision,
            UnreachablePose,
            Timeout,
            WrongDof,
            NotFinite,
            VersionMismatch,
            BadRequest,
            UnknownLink,
            Internal,
            Cancelled,
            UnknownObject,
            AlreadyAttached,
            NotAttached,
            AttachCollides,
        ]
        .into_iter()
        .find(|s| *s as u32 == code)
    }

    /// Its name in snake case (`ok`, `start_in_collision`, ...), as in logs and JSON.
    pub fn name(self) -> &'static str {
        use Status::*;
        match self {
            Ok => "ok",
            InvalidStart => "invalid_start",
            StartInCollision => "start_in_collision",
            InvalidGoal => "invalid_goal",
            GoalInCollision => "goal_in_collision",
            UnreachablePose => "unreachable_pose",
            Timeout => "timeout",
            WrongDof => "wrong_dof",
            NotFinite => "not_finite",
            VersionMismatch => "version_mismatch",
            BadRequest => "bad_request",
            UnknownLink => "unknown_link",
            Internal => "internal",
            Cancelled => "cancelled",
            UnknownObject => "unknown_object",
            AlreadyAttached => "already_attached",
            NotAttached => "not_attached",
            AttachCollides => "attach_collides",
        }
    }
}
