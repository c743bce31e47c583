#include "elastogen/Simulation.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <functional>

#include <fmt/ranges.h>

#include "core/BuildInfo.hpp"
#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "parallel/Collective.hpp"
#include "core/Log.hpp"
#include "parallel/Signals.hpp"
#include "core/Progress.hpp"
#include "gaussians/DeckSplats.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/Video.hpp"
#include "geometry/Shape.hpp"
#include "io/Checkpoint.hpp"
#include "io/FrameWriter.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::elastogen {

namespace {

io::NodeBox to_io(const Box& b) {
  return io::NodeBox{b.start, b.count};
}

//! Part i of the deck alone, its errors naming [[geometry]] #i + 1 as make_shape does.
std::unique_ptr<geometry::Shape> make_part(const GeometryConfig& g, std::size_t i) {
  try {
    return geometry::make_shape({g});
  } catch (const InputError& e) {
    std::string msg = e.what();
    const std::string alone = fmt::format("[[geometry]] #1 ({}): ", g.type);
    if (msg.rfind(alone, 0) == 0) msg.erase(0, alone.size());
    throw InputError(fmt::format("[[geometry]] #{} ({}): {}", i + 1, g.type, msg));
  }
}

}  // namespace

Vec3d cell_edges(const Config& cfg) {
  return cfg.cell_edges();
}

DomainLayout layout_domain(const Config& cfg, const geometry::Shape& shape) {
  return layout_domain(cfg, shape.bounds());
}

DomainLayout layout_domain(const Config& cfg, const geometry::Aabb& b) {
  DomainLayout d;
  const Vec3d edges = cell_edges(cfg);
  for (int a = 0; a < 3; ++a) {
    const double h = edges[a];
    const long cells = static_cast<long>(std::ceil((b.hi[a] - b.lo[a]) / h - 1e-9));
    d.nodes[a] = std::max(1L, cells) + 2L * cfg.padding + 1;
    d.origin[a] = b.lo[a] - cfg.padding * h;
    if (d.nodes[a] > 100000000L)
      throw InputError(cfg.source + ": key 'domain.voxel_size': " + std::to_string(d.nodes[a]) +
                       " nodes along one axis; the voxel size is too small for the object");
  }
  return d;
}

DeckObject build_deck_object(const Config& cfg) {
  DeckObject obj;
  const std::size_t n = cfg.geometry.size();
  for (const auto& g : cfg.geometry)
    obj.has_splat_parts = obj.has_splat_parts || g.type == "splats";
  obj.has_splats = obj.has_splat_parts || cfg.render.enabled;
  const bool by_part = std::any_of(cfg.material_regions.begin(), cfg.material_regions.end(),
                                   [](const MaterialConfig& m) { return !m.has_region; });
  if (!obj.has_splats) {
    obj.shape = geometry::make_shape(cfg.geometry);
    obj.layout = layout_domain(cfg, *obj.shape);
    if (by_part)
      for (std::size_t i = 0; i < n; ++i) {
        obj.own_parts.push_back(make_part(cfg.geometry[i], i));
        obj.parts.push_back(obj.own_parts.back().get());
      }
    return obj;
  }
  if (n == 0) throw InputError("the object has no geometry parts");
  std::vector<std::unique_ptr<geometry::Shape>> parts(n);
  std::vector<gaussians::SplatSet> loaded(n);
  geometry::Aabb bounds;
  for (std::size_t i = 0; i < n; ++i) {
    const GeometryConfig& g = cfg.geometry[i];
    if (g.type != "splats") {
      parts[i] = make_part(g, i);
      bounds.extend(parts[i]->bounds());
      continue;
    }
    try {
      loaded[i] = gaussians::load_geometry_splats(g);
    } catch (const InputError& e) {
      throw InputError(fmt::format("[[geometry]] #{} (splats): {}", i + 1, e.what()));
    }
    const auto& p = loaded[i].position;
    for (std::size_t k = 0; k + 2 < p.size(); k += 3)
      bounds.extend(Eigen::Vector3d(p[k], p[k + 1], p[k + 2]));
  }
  if (obj.has_splat_parts && !cfg.cubic_cells())
    throw InputError(cfg.source +
                     ": key 'domain.voxel_size': [[geometry]] type = \"splats\" needs cubic "
                     "cells (one voxel_size)");
  obj.layout = layout_domain(cfg, bounds);
  const Vec3d edges = cell_edges(cfg);
  const double spacing = cfg.render.splat_spacing > 0
                             ? cfg.render.splat_spacing
                             : 0.5 * std::min({edges[0], edges[1], edges[2]});
  for (std::size_t i = 0; i < n; ++i) {
    const GeometryConfig& g = cfg.geometry[i];
    if (g.type == "splats") {
      gaussians::append_splats(obj.splats, loaded[i]);
      parts[i] =
          std::make_unique<gaussians::SplatOccupancy>(loaded[i], cfg.voxel_size, obj.layout.origin);
      loaded[i] = gaussians::SplatSet();  // the occupancy keeps its own cells
    } else {
      gaussians::append_splats(obj.splats,
                               gaussians::splats_from_shape(*parts[i], spacing, g.color));
    }
  }
  if (by_part)
    for (const auto& part : parts) obj.parts.push_back(part.get());
  if (parts.size() == 1)
    obj.shape = std::move(parts.front());
  else
    obj.shape = std::make_unique<geometry::Union>(std::move(parts));
  return obj;
}

Simulation::Simulation(MPI_Comm comm, const Config& cfg)
    : comm_(comm), cfg_(cfg), spacing_(cell_edges(cfg)) {
  rank_ = parallel::rank(comm);
  size_ = parallel::size(comm);
  if (cfg_.render.enabled) {  // bad render settings fail before the set-up's work
    kinematics_ = gaussians::KinematicsOptions::parse(cfg_.render.kinematics, "render.kinematics");
    renderer_ = std::make_unique<gaussians::RunRenderer>(comm_, cfg_.render);
  }
  DeckObject object = [&] {
    PhaseTimers::Scope t(timers_, "voxelize");
    return build_deck_object(cfg_);
  }();
  const std::unique_ptr<geometry::Shape> shape = std::move(object.shape);
  layout_ = object.layout;
  if (renderer_) renderer_->frame_object(object.splats, {1, 1, 1}, {0, 0, 0});
  grid_ = std::make_unique<parallel::NodeGrid>(comm, layout_.nodes);
  std::vector<std::uint8_t> occ;
  {
    PhaseTimers::Scope t(timers_, "voxelize");
    const Box& c = grid_->adjacent_cells();
    const std::array<long, 3> hi{c.start[0] + c.count[0], c.start[1] + c.count[1],
                                 c.start[2] + c.count[2]};
    geometry::voxelize(*shape,
                       Eigen::Vector3d(layout_.origin[0], layout_.origin[1], layout_.origin[2]),
                       Eigen::Vector3d(spacing_[0], spacing_[1], spacing_[2]), c.start, hi, occ);
  }
  // Occupancy 1 + the material slot of each solid voxel, judged at its centre.
  std::vector<double> density{cfg_.material.density};
  for (const MaterialConfig& m : cfg_.material_regions) density.push_back(m.density);
  if (!cfg_.material_regions.empty()) {
    const Box& c = grid_->adjacent_cells();
    for (long k = c.start[2]; k < c.start[2] + c.count[2]; ++k)
      for (long j = c.start[1]; j < c.start[1] + c.count[1]; ++j)
        for (long i = c.start[0]; i < c.start[0] + c.count[0]; ++i) {
          std::uint8_t& o = occ[c.index(i, j, k)];
          if (!o) continue;
          const Vec3d& h = spacing_;
          const Vec3d x{layout_.origin[0] + (i + 0.5) * h[0], layout_.origin[1] + (j + 0.5) * h[1],
                        layout_.origin[2] + (k + 0.5) * h[2]};
          int part = -1;
          for (std::size_t p = 0; p < object.parts.size() && part < 0; ++p)
            if (object.parts[p]->inside(Eigen::Vector3d(x[0], x[1], x[2])))
              part = static_cast<int>(p);
          o = static_cast<std::uint8_t>(1 + material_slot(cfg_, part, x));
        }
  }
  std::vector<BoxRegion> held;
  for (const auto& f : cfg_.fixed) held.push_back(f.region);
  for (const auto& k : cfg_.kinematic) held.push_back(k.region);
  sys_ = std::make_unique<VoxelSystem>(*grid_, layout_.origin, spacing_, std::move(occ), density,
                                       held);
  if (sys_->global_solid_cells() == 0)
    throw InputError(cfg_.source + ": [[geometry]] produces no solid voxel at voxel_size " +
                     fmt::format("{:g}", cfg_.voxel_size) + " m; use a smaller voxel_size");
  // Every node prescribed is a valid (rigid-body) scene only when some of them move.
  if (sys_->global_free_nodes() == 0 && cfg_.kinematic.empty())
    throw InputError(cfg_.source + ": [[fixed]] regions hold every node; nothing can move");
  sys_->add_point_masses(cfg_.point_masses);
  for (const PointMassConfig& pm : cfg_.point_masses)
    log::info("point mass {:g} kg on [{}] .. [{}] ({})", pm.mass, fmt::join(pm.region.lo, ", "),
              fmt::join(pm.region.hi, ", "), pm.where);
  {
    PhaseTimers::Scope t(timers_, "setup");
    dyn_ = std::make_unique<Elastodynamics>(*sys_, cfg_, timers_);
  }
  log::info(
      "gen4d {}: '{}' on {} rank(s): grid {}x{}x{} nodes, {} solid voxels, {} free nodes "
      "({} DoFs), h = {} m, k = {:.4g} Pa, {} subspace modes",
      build::version, cfg_.name, size_, layout_.nodes[0], layout_.nodes[1], layout_.nodes[2],
      sys_->global_solid_cells(), sys_->global_free_nodes(), 3 * sys_->global_free_nodes(),
      sys_->cubic() ? fmt::format("{:g}", spacing_[0])
                    : fmt::format("[{:g}, {:g}, {:g}]", spacing_[0], spacing_[1], spacing_[2]),
      dyn_->stiffness(), dyn_->global_solver().subspace_modes());
  if (cfg_.output.surface != "none") {
    PhaseTimers::Scope t(timers_, "setup");
    io::parse_surface_format(cfg_.output.surface, surface_format_);
    surface_ = std::make_unique<SurfaceEmbedding>(*sys_, *shape, choose_surface_source(cfg_));
    if (rank_ == 0) surface_mesh_.triangles = surface_->triangles();
    const bool mesh = surface_->source() == SurfaceSource::Mesh;
    log::info("surface: {} with {} vertices, {} triangles, written as {}{}",
              mesh ? "input mesh" : "voxel boundary", surface_->vertex_count(),
              surface_->triangle_count(), cfg_.output.surface,
              mesh && surface_->extrapolated_vertices() > 0
                  ? fmt::format("; {} vertices lie outside the solid voxels and follow the "
                                "nearest one (at most {:.2f} voxel away)",
                                surface_->extrapolated_vertices(), surface_->max_extrapolation())
                  : std::string());
  }
  if (object.has_splats) {
    PhaseTimers::Scope t(timers_, "setup");
    splats_ = std::make_unique<SplatEmbedding>(*sys_, *shape, object.splats);
    object.splats = gaussians::SplatSet();
    log::info("splats: {} Gaussian(s) of SH degree {} ride the voxels{}", splats_->count(),
              splats_->sh_degree(),
              splats_->extrapolated() > 0
                  ? fmt::format("; {} lie outside the solid voxels and follow the nearest one "
                                "(at most {:.2f} voxel away)",
                                splats_->extrapolated(), splats_->max_extrapolation())
                  : std::string());
  }
}

Simulation::~Simulation() = default;

std::vector<double> Simulation::pack_owned(const std::vector<double>& field) const {
  const Box& O = grid_->owned_nodes();
  const Box& G = grid_->ghosted_nodes();
  std::vector<double> out(3 * O.size());
  std::size_t p = 0;
  for (long k = O.start[2]; k < O.start[2] + O.count[2]; ++k)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
      for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i, ++p)
        for (int d = 0; d < 3; ++d) out[3 * p + d] = field[3 * G.index(i, j, k) + d];
  return out;
}

void Simulation::unpack_owned(const std::vector<double>& packed, std::vector<double>& field) const {
  const Box& O = grid_->owned_nodes();
  const Box& G = grid_->ghosted_nodes();
  std::size_t p = 0;
  for (long k = O.start[2]; k < O.start[2] + O.count[2]; ++k)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
      for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i, ++p)
        for (int d = 0; d < 3; ++d) field[3 * G.index(i, j, k) + d] = packed[3 * p + d];
}

std::vector<double> Simulation::owned_positions() const {
  return pack_owned(dyn_->x());
}
std::vector<double> Simulation::owned_velocities() const {
  return pack_owned(dyn_->v());
}

std::vector<std::uint8_t> Simulation::owned_occupancy() const {
  const Box& oc = grid_->owned_cells();
  std::vector<std::uint8_t> out(oc.size());
  std::size_t p = 0;
  for (long k = oc.start[2]; k < oc.start[2] + oc.count[2]; ++k)
    for (long j = oc.start[1]; j < oc.start[1] + oc.count[1]; ++j)
      for (long i = oc.start[0]; i < oc.start[0] + oc.count[0]; ++i, ++p)
        out[p] = sys_->solid(i, j, k) ? 1 : 0;
  return out;
}

void Simulation::load_checkpoint(const std::string& path) {
  std::vector<double> x, v;
  const io::CheckpointMeta meta =
      io::read_checkpoint(comm_, path, to_io(grid_->owned_nodes()), x, v);
  if (meta.node_dims != layout_.nodes)
    throw InputError(
        path + ": checkpoint grid " + fmt::format("{}", fmt::join(meta.node_dims, "x")) +
        " does not match the deck's grid " + fmt::format("{}", fmt::join(layout_.nodes, "x")));
  unpack_owned(x, dyn_->x());
  unpack_owned(v, dyn_->v());
  dyn_->sync_ghosts();
  started_ = true;
  step_ = meta.step;
  time_ = meta.time;
  frame_index_ = meta.frame_index;
  next_frame_time_ = meta.next_frame_time;
  log::info("restarted from {} at step {}, t = {:.6g} s", path, step_, time_);
}

void Simulation::prepare_start() {
  if (started_) return;
  started_ = true;
  if (dyn_->has_preloads()) {
    PhaseTimers::Scope t(timers_, "setup");
    dyn_->settle_preloads();
  }
}

std::string Simulation::write_checkpoint(const std::string& out_dir) {
  PhaseTimers::Scope t(timers_, "io");
  const auto x = owned_positions();
  const auto v = owned_velocities();
  io::CheckpointState s;
  s.step = static_cast<int>(step_);
  s.time = time_;
  s.frame_index = static_cast<int>(frame_index_);
  s.next_frame_time = next_frame_time_;
  s.deck_text = cfg_.text;
  s.node_dims = layout_.nodes;
  s.owned = to_io(grid_->owned_nodes());
  s.x = x.data();
  s.v = v.data();
  return io::write_checkpoint(comm_, out_dir, s, cfg_.output.checkpoint_keep);
}

std::unique_ptr<io::FrameWriter> Simulation::open_frames(const std::string& out_dir, bool append) {
  PhaseTimers::Scope t(timers_, "io");
  parallel::on_rank0(comm_, out_dir + ": cannot create directory", [&] {
    std::error_code ec;
    std::filesystem::create_directories(out_dir, ec);
    if (ec) throw RuntimeError(out_dir + ": cannot create the output directory: " + ec.message());
  });
  const std::string path = (std::filesystem::path(out_dir) / "frames.h5").string();
  if (append)
    return std::make_unique<io::FrameWriter>(
        io::FrameWriter::open_append(comm_, path, static_cast<int>(step_)));
  io::GridMeta meta;
  meta.node_dims = layout_.nodes;
  meta.origin = layout_.origin;
  meta.spacing = sys_->h();
  meta.attributes = {
      {"deck", cfg_.text},
      {"cell_edges", fmt::format("{:.17g} {:.17g} {:.17g}", spacing_[0], spacing_[1], spacing_[2])},
      {"version", build::version},
      {"git_revision", build::git_revision},
      {"ranks", std::to_string(size_)},
      {"solver", "elastogen"}};
  auto writer = std::make_unique<io::FrameWriter>(comm_, path, meta);
  writer->write_occupancy(to_io(grid_->owned_cells()), owned_occupancy().data());
  return writer;
}

void Simulation::write_frame(io::FrameWriter& writer) {
  {
    PhaseTimers::Scope t(timers_, "io");
    const auto x = owned_positions();
    const auto v = owned_velocities();
    writer.write_frame(time_, static_cast<int>(step_), to_io(grid_->owned_nodes()), x.data(),
                       v.data());
    if (surface_) write_surface(writer.frames().back().index);
  }
  if (renderer_) render_frame(writer.frames().back().index);
  ++frame_index_;
  next_frame_time_ = time_ + cfg_.output.frame_interval;
}

void Simulation::open_surface(const std::string& out_dir, const io::FrameWriter& writer) {
  if (!surface_) return;
  PhaseTimers::Scope t(timers_, "io");
  surface_dir_ = (std::filesystem::path(out_dir) / io::kSurfaceDir).string();
  // Frames later than the last one kept were dropped from frames.h5 (or all, for a fresh run).
  const long keep = writer.frames().empty() ? -1 : writer.frames().back().index;
  parallel::on_rank0(comm_, surface_dir_ + ": cannot prepare", [&] {
    std::error_code ec;
    std::filesystem::create_directories(surface_dir_, ec);
    if (ec) throw RuntimeError(surface_dir_ + ": cannot create directory: " + ec.message());
    io::prune_surface_sequence(surface_dir_, keep);
  });
}

void Simulation::write_surface(long index) {
  const double start = parallel::wall_seconds();
  // Ghost positions are current after every step, reset and restart (Elastodynamics keeps
  // them so), which is all the corners of owned voxels need.
  std::vector<double> xyz = surface_->gather(dyn_->x().data());
  const double gathered = parallel::wall_seconds();
  surface_gather_seconds_ += gathered - start;
  parallel::on_rank0(comm_, surface_dir_ + ": surface write failed", [&] {
    surface_mesh_.xyz = std::move(xyz);
    surface_mesh_.comments = {fmt::format(
        "gen4d surface of '{}': frame {} step {} time {} s, {}", cfg_.name, index, step_, time_,
        surface_->source() == SurfaceSource::Mesh ? "input mesh" : "voxel boundary")};
    const std::string path =
        (std::filesystem::path(surface_dir_) / io::surface_file_name(index, surface_format_))
            .string();
    io::write_surface(path, surface_mesh_, surface_format_);
    std::error_code ec;
    surface_bytes_ += static_cast<double>(std::filesystem::file_size(path, ec));
  });
  ++surface_files_;
  surface_write_seconds_ += parallel::wall_seconds() - gathered;
}

void Simulation::render_frame(long index) {
  PhaseTimers::Scope t(timers_, "render");
  // Ghost positions are current after every step, reset and restart.
  renderer_->render(index, splats_->frame(dyn_->x().data(), kinematics_));
}

RunResult Simulation::run(const std::string& out_dir, bool append) {
  RunResult res;
  auto writer = open_frames(out_dir, append);
  open_surface(out_dir, *writer);
  if (renderer_) {
    PhaseTimers::Scope t(timers_, "render");
    // Images later than the last frame kept belong to a run that frames.h5 no longer holds.
    renderer_->open(out_dir, writer->frames().empty() ? -1 : writer->frames().back().index);
  }
  const double dt = cfg_.dt;
  const long total_steps = static_cast<long>(std::ceil(cfg_.end_time / dt - 1e-9));
  if (!append && step_ == 0) {
    prepare_start();
    write_frame(*writer);
  }
  ProgressLog progress(step_, total_steps, cfg_.output.progress_interval);
  while (step_ < total_steps) {
    const StepStats st = dyn_->step(time_);
    ++step_;
    time_ = step_ * dt;
    progress.record(st.outer, st.sweeps, st.accuracy, st.accurate);
    if (!st.accurate)
      log::info(
          "step {}: residual {:.2e} still above solver.accuracy_tolerance after {} extra "
          "loop(s)",
          step_, st.accuracy, st.extra);
    if (time_ + 1e-12 * dt >= next_frame_time_ || step_ == total_steps) write_frame(*writer);
    const int sig = signals::pending(comm_);
    const bool periodic = cfg_.output.checkpoint_every > 0 &&
                          step_ % cfg_.output.checkpoint_every == 0 && step_ < total_steps;
    if (sig != 0 || periodic) res.last_checkpoint = write_checkpoint(out_dir);
    if (sig != 0)
      log::info("received {}: checkpoint {} written at step {}",
                sig == SIGTERM ? "SIGTERM" : "SIGUSR1", res.last_checkpoint, step_);
    if (sig == SIGTERM) {
      log::info("stopping; resume with: gen4d restart {}", res.last_checkpoint);
      res.exit_code = 1;
      break;
    }
    progress.maybe_print(step_, time_);
  }
  if (res.exit_code == 0) res.last_checkpoint = write_checkpoint(out_dir);
  writer.reset();
  res.steps = progress.steps();
  res.wall_seconds = progress.elapsed();
  if (progress.inaccurate_steps() > 0)
    log::info("warning: {} step(s) ended above solver.accuracy_tolerance (worst {:.2e})",
              progress.inaccurate_steps(), progress.worst_residual());
  if (surface_ && surface_files_ > 0)
    log::info(
        "surface: {} file(s) in {}, {:.2f} MB; per frame {:.2f} ms evaluate + gather, {:.2f} ms "
        "write",
        surface_files_, surface_dir_, surface_bytes_ / 1e6,
        1e3 * surface_gather_seconds_ / static_cast<double>(surface_files_),
        1e3 * surface_write_seconds_ / static_cast<double>(surface_files_));
  if (renderer_ && renderer_->images() > 0)
    log::info("render: {} image(s) in {}; {:.2f} s per frame (splat kinematics + render + write)",
              renderer_->images(), renderer_->png_dir(),
              timers_.total("render") / static_cast<double>(renderer_->images()));
  if (renderer_ && res.exit_code == 0) {
    PhaseTimers::Scope t(timers_, "render");
    renderer_->finish(cfg_.output.frame_interval > 0 ? cfg_.output.frame_interval : cfg_.dt);
  }
  report_timers(res.wall_seconds, res.steps);
  return res;
}

void Simulation::report_timers(double wall, long steps) const {
  // The slowest rank's time per phase is what bounds the run.
  const char* phases[] = {"voxelize", "setup",     "stencil+svd", "subspace", "sweeps",
                          "halo",     "reduction", "io",          "render"};
  log::info("phase timers (max over ranks, wall {:.2f} s, {:.2f} steps/s):", wall,
            static_cast<double>(steps) / std::max(wall, 1e-9));
  for (const char* p : phases) {
    if (std::string(p) == "render" && !cfg_.render.enabled) continue;
    const double global = parallel::max_of(comm_, timers_.total(p));
    log::info("  {:<12} {:9.3f} s  {:5.1f} %", p, global, 100.0 * global / std::max(wall, 1e-9));
  }
}

}  // namespace gen4d::elastogen
