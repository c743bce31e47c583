//! The gen4d subcommands (run, restart, info, preview) behind one CLI11 parser.
#pragma once

namespace gen4d::cli {

//! Parses argv and runs the chosen subcommand; returns the process exit code.
//! Throws CLI::ParseError, InputError or RuntimeError.
int dispatch(int argc, char** argv);

}  // namespace gen4d::cli
