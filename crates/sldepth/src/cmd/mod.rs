//! One module per subcommand.

pub mod analyze;
pub mod cloud;
pub mod filter;
pub mod fuse;
pub mod info;
pub mod motion;
pub mod planes;
pub mod simulate;
// @commands-modules (add `pub mod name;` above this line)
