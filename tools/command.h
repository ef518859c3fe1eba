// Subcommand registry of the `banmo` executable. Each tools/cmd_<name>.cc
// defines `int Run<Name>(int argc, char** argv)` (parse with CLI11, check
// options and paths, call the library, write outputs: no algorithm code here)
// and registers it:
//   BANMO_REGISTER_COMMAND(synth, "Render a synthetic multi-video dataset", RunSynth);
// argv[0] of the call is "banmo <name>".
#pragma once

#include <functional>
#include <map>
#include <string>

namespace banmo::tools {

struct Command {
  std::string summary;
  std::function<int(int, char**)> run;
};

std::map<std::string, Command>& CommandRegistry();

struct CommandRegistrar {
  CommandRegistrar(const std::string& name, const std::string& summary,
                   std::function<int(int, char**)> run) {
    CommandRegistry()[name] = Command{summary, std::move(run)};
  }
};

}  // namespace banmo::tools

#define BANMO_REGISTER_COMMAND(name, summary, fn) \
  static ::banmo::tools::CommandRegistrar banmo_command_registrar_##name(#name, summary, fn)
