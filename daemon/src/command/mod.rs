//! One file per subcommand.

mod demo;
mod monitor;
mod plan;
mod problems;
mod replay;
mod robot;
mod run;
mod train;

use crate::cli::{Cli, Command};
use std::process::ExitCode;

/// Runs the chosen subcommand. `Err` is bad input (exit 2); a planning failure is exit 1.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Run(a) => run::run(a),
        Command::Plan(a) => plan::run(a),
        Command::Problems(a) => problems::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Train(a) => train::run(a),
        Command::Monitor(a) => monitor::run(a),
        Command::Robot(c) => robot::run(c),
    }
}

/// Loads a robot by built-in name or robot-file path, with a sentence naming the input.
pub fn load_robot(
    spec: &ember_engine::robot::RobotSpec,
) -> anyhow::Result<ember_engine::robot::Robot> {
    spec.load()
        .map_err(|e| anyhow::anyhow!("cannot load robot '{}': {e}", spec.robot))
}

/// The robot's planning-group positions picked by name from a joint state (`None` when a group
/// joint is missing); unnamed positions of the group's length pass through as they are.
pub fn group_order(
    robot: &ember_engine::robot::Robot,
    names: &[String],
    positions: &[f64],
) -> Option<Vec<f64>> {
    if names.is_empty() {
        return (positions.len() == robot.dof()).then(|| positions.to_vec());
    }
    robot.group_positions(names, positions).ok()
}
