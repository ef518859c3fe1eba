#include "command.h"

namespace banmo::tools {

std::map<std::string, Command>& CommandRegistry() {
  static std::map<std::string, Command> registry;
  return registry;
}

}  // namespace banmo::tools
