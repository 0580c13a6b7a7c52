//! One module per subcommand.

pub mod analyze;
pub mod cloud;
pub mod info;
pub mod simulate;
pub mod fuse;
pub mod filter;
// @commands-modules (add `pub mod name;` above this line)
