//! gen4d render: one image of a 3DGS point cloud from a cameras.json view or an orbit camera.
#pragma once

#include <memory>

namespace CLI {
class App;
}

namespace gen4d::cli {

class RenderCommand {
 public:
  //! Adds the subcommand to `app`.
  explicit RenderCommand(CLI::App& app);
  ~RenderCommand();
  //! After parsing: renders and returns the exit code, or -1 when `render` was not chosen.
  int run() const;

 private:
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace gen4d::cli
