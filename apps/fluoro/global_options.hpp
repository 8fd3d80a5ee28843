#pragma once
// The options every subcommand takes, on the main program so that they mean the same everywhere
// (docs/cli.md, "Options of every command"): `--threads N`, `-q/--quiet`, `-v/--verbose`. They may
// be given before or after the subcommand's name (CLI11's fallthrough).
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace fluoro::cli {

// Adds the options to the main program; call before adding the subcommands (they inherit the
// fallthrough). `argv` is kept for the result files' provenance.
void add_global_options(CLI::App& app, int argc, char** argv);

// Ends every subcommand's --help (nested ones too) with those options, which only the main
// program's help lists otherwise. Call after adding the subcommands.
void name_global_options_in_help(CLI::App& app);

// -q: nothing printed on success (stdout goes to /dev/null; commands also skip their stderr progress).
bool quiet();
// -v: the version and thread limit, each input's digest and the total time, on stderr.
bool verbose();

// The program's arguments after its name, as given.
const std::vector<std::string>& arguments();

}  // namespace fluoro::cli
