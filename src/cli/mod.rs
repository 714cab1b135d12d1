//! The subcommands that render: `render` and `sweep`.

pub mod plot;
pub mod render;
pub mod sweep;
pub mod sweep_output;
