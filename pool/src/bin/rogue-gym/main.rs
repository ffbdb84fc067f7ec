//! The `rogue-gym` command-line tool (work in progress).
fn main() {}
