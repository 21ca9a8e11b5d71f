//! The command tree as a newcomer meets it: every command says what it does, and every
//! argument and every value it offers has a help line.

use super::Cli;
use clap::CommandFactory;

/// Calls `visit` with every command under `command` (itself included) and its path.
fn walk(command: &clap::Command, path: &str, visit: &mut dyn FnMut(&str, &clap::Command)) {
    visit(path, command);
    for sub in command.get_subcommands() {
        walk(sub, &format!("{path} {}", sub.get_name()), visit);
    }
}

fn arg_name(arg: &clap::Arg) -> String {
    match (arg.get_long(), arg.get_short()) {
        (Some(long), _) => format!("--{long}"),
        (None, Some(short)) => format!("-{short}"),
        (None, None) => format!("<{}>", arg.get_id().as_str().to_uppercase()),
    }
}

#[test]
fn every_command_argument_and_value_has_help() {
    let mut root = Cli::command();
    root.build();
    let mut missing = Vec::new();
    let mut args = 0;
    walk(&root, "mema", &mut |path, command| {
        if command.get_about().is_none() && command.get_long_about().is_none() {
            missing.push(format!("{path}: no description"));
        }
        for arg in command.get_arguments() {
            args += 1;
            if arg.get_help().is_none() && arg.get_long_help().is_none() {
                missing.push(format!("{path} {}: no help", arg_name(arg)));
            }
            // Shell names need no definition, and clap_complete gives them none.
            if !arg.get_action().takes_values() || path == "mema completions" {
                continue;
            }
            for value in arg.get_possible_values() {
                if value.get_help().is_none() && !value.is_hide_set() {
                    missing.push(format!(
                        "{path} {} {}: no help",
                        arg_name(arg),
                        value.get_name()
                    ));
                }
            }
        }
    });
    // The walk reached the tree: a broken walk would pass on nothing.
    assert!(args >= 150, "only {args} arguments walked");
    assert!(missing.is_empty(), "help missing:\n{}", missing.join("\n"));
}

#[test]
fn the_main_help_defines_its_terms() {
    let help = Cli::command().render_help().to_string();
    for term in [
        "eq. 12",
        "eq. 13",
        "entity",
        "pseudocylinder",
        "Table 2",
        "mema demo",
    ] {
        assert!(help.contains(term), "`mema --help` lacks {term:?}:\n{help}");
    }
}
