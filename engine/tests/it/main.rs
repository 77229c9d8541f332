//! Engine integration tests, one binary.

mod collision;
mod fk;
