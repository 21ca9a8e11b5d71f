//! One handler per subcommand: check the arguments, call the library, print.
pub mod bench;
pub mod eval;
pub mod info;
pub mod map;
pub mod query;
pub mod serial;
pub mod toolbox;
