//! The subcommands that render: `render` and `sweep`.

pub mod plot;
pub mod render;
pub mod sweep;
pub mod sweep_output;

/// Each spec flag's help with its default, as the spec has it (`spec::default_text`): the
/// defaults are written once, in the spec, and shown wherever a front end names them.
pub fn with_spec_defaults(cmd: clap::Command) -> clap::Command {
    let ids: Vec<String> = cmd
        .get_arguments()
        .map(|a| a.get_id().to_string())
        .collect();
    ids.into_iter().fold(cmd, |cmd, id| {
        let Some(default) = photonbox::spec::default_text(&id) else {
            return cmd;
        };
        cmd.mut_arg(&id, |a| {
            let help = a.get_help().map(|h| h.to_string()).unwrap_or_default();
            a.help(format!("{help} [default: {default}]"))
        })
    })
}
