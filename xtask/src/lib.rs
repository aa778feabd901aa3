//! The developer tasks' library: what a task shares with the tests (`xtask/tests`).

pub mod import_fixture;
