//! Engine integration tests, one binary.

mod collision;
mod experience;
mod fk;
mod fuzz;
mod map;
mod moveit;
mod planning;
mod robot;
mod trajectory;
mod world;

/// The repository's `tests/fixtures` folder.
pub fn fixtures() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures")
}
