//! The NeuralMTL subcommands: train-material, train-generator, make-material. They exist in
//! every build; without LibTorch they fail with exit code 2 and say how to get it.
#pragma once

#include <memory>

namespace CLI {
class App;
}

namespace gen4d::cli {

class NeuralCommands {
 public:
  //! Adds the three subcommands to `app`.
  explicit NeuralCommands(CLI::App& app);
  ~NeuralCommands();
  //! After parsing: runs the chosen NeuralMTL subcommand and returns its exit code, or -1 if
  //! none of them was chosen.
  int run() const;

 private:
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace gen4d::cli
