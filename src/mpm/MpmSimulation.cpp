#include "mpm/MpmSimulation.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>

#include "core/Log.hpp"
#include "core/Progress.hpp"
#include "materials/J2Return.hpp"
#include "parallel/Signals.hpp"
#include "geometry/Shape.hpp"
#include "io/Checkpoint.hpp"
#include "io/Hdf5.hpp"
#include "gaussians/DeckSplats.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/Video.hpp"
#include "mpm/PointMass.hpp"
#include "mpm/Seeding.hpp"
#include "parallel/Comm.hpp"
#include "parallel/Reduce.hpp"

namespace gen4d::mpm {
namespace fs = std::filesystem;

namespace {

//! Splat attributes of lattice particles: isotropic splats of standard deviation half the
//! spacing (render.splat_spacing, else the particle spacing), coloured by the first of
//! `parts` (deck order) that holds the particle.
void add_lattice_splats(Particles& p, const SplatLayout& layout, const Config& cfg,
                        const std::vector<GeometryConfig>& parts, double particle_spacing) {
  const double spacing = cfg.render.splat_spacing > 0 ? cfg.render.splat_spacing : particle_spacing;
  std::vector<std::unique_ptr<geometry::Shape>> shapes;
  if (parts.size() > 1)
    for (const GeometryConfig& g : parts) shapes.push_back(geometry::make_shape({g}));
  const int W = layout.width();
  p.extra_width = W;
  p.extra.assign(static_cast<std::size_t>(W) * p.size(), 0.0);
  for (std::size_t i = 0; i < p.size(); ++i) {
    std::size_t part = 0;
    const Eigen::Vector3d x(p.x[3 * i], p.x[3 * i + 1], p.x[3 * i + 2]);
    while (part + 1 < shapes.size() && !shapes[part]->inside(x)) ++part;
    isotropic_rest_values(0.5 * spacing, 0.95, parts[part].color.data(), layout,
                          &p.extra[static_cast<std::size_t>(W) * i]);
  }
}

}  // namespace

std::vector<BoundaryConfig> boundary_conditions(const Config& cfg) {
  std::vector<BoundaryConfig> out = cfg.boundaries;
  for (const ColliderConfig& c : cfg.colliders) {
    if (c.type == "plane") {
      const double len = std::sqrt(c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1] +
                                   c.normal[2] * c.normal[2]);
      out.push_back(surface_collider("separate", c.point,
                                     {c.normal[0] / len, c.normal[1] / len, c.normal[2] / len},
                                     c.friction));
    } else {
      BoundaryConfig b;
      b.type = "cuboid";
      b.region = c.box;
      out.push_back(b);
    }
  }
  return out;
}

WallCount particles_at_walls(MPI_Comm comm, const GridSpec& spec, int layers, const Particles& p) {
  std::array<long long, 7> count{};  // per wall, then particles
  if (layers > 0) {
    // A particle's quadratic B-spline reaches the nodes floor(X - 0.5) .. floor(X - 0.5) + 2
    // (X its position in cells); the walls are nodes [0, layers) and (cells - layers, cells].
    for (std::size_t i = 0; i < p.size(); ++i) {
      bool any = false;
      for (int d = 0; d < 3; ++d) {
        const double X = (p.x[3 * i + d] - spec.lo[d]) / spec.dx;
        const bool low = X < layers + 0.5;
        const bool high = X >= static_cast<double>(spec.cells[d] - layers) - 0.5;
        count[2 * d] += low;
        count[2 * d + 1] += high;
        any = any || low || high;
      }
      count[6] += any;
    }
  }
  std::array<parallel::ExactSum, 7> local;
  for (int w = 0; w < 7; ++w) local[w].add(static_cast<double>(count[w]));
  std::array<double, 7> global{};
  parallel::Reducer(comm).sum(local.data(), global.data(), 7);
  WallCount out;
  for (int w = 0; w < 6; ++w) out.per_wall[w] = static_cast<long long>(global[w]);
  out.particles = static_cast<long long>(global[6]);
  return out;
}

namespace {
//! "z-: 120, x+: 3" for the walls holding particles.
std::string describe_walls(const std::array<long long, 6>& count) {
  std::string out;
  for (int w = 0; w < 6; ++w)
    if (count[w] > 0)
      out += fmt::format("{}{}{}: {}", out.empty() ? "" : ", ", "xyz"[w / 2], w % 2 ? '+' : '-',
                         count[w]);
  return out;
}
}  // namespace

GridSpec layout_grid(const Config& cfg, const geometry::Aabb& object) {
  GridSpec g;
  g.dx = cfg.voxel_size;
  Vec3d lo, hi;
  if (cfg.mpm.has_box) {
    lo = cfg.mpm.lo;
    hi = cfg.mpm.hi;
  } else {
    const int pad = std::max(cfg.padding, cfg.mpm.boundary_layers + 2);
    for (int a = 0; a < 3; ++a) {
      lo[a] = object.lo[a] - pad * g.dx;
      hi[a] = object.hi[a] + pad * g.dx;
    }
  }
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = lo[a];
    g.cells[a] = static_cast<long>(std::ceil((hi[a] - lo[a]) / g.dx - 1e-9));
    if (g.cells[a] > 100000L)
      throw InputError(
          fmt::format("{}: key 'domain.voxel_size': {} MPM cells along one axis; the "
                      "cell size is too small for the grid box",
                      cfg.source, g.cells[a]));
  }
  return g;
}

namespace {
std::shared_ptr<const Material> build_material(const MaterialConfig& m, const std::string& source) {
  MaterialParams p;
  p.model = m.model;
  p.values = m.params;
  p.where = m.param_where;
  p.values["youngs_modulus"] = m.youngs_modulus;
  p.values["poisson_ratio"] = m.poisson_ratio;
  p.values["density"] = m.density;
  p.source = source;
  return make_material(p);
}
}  // namespace

std::shared_ptr<const Material> make_deck_material(const Config& cfg) {
  return build_material(cfg.material, cfg.source);
}

MaterialSet make_deck_materials(const Config& cfg) {
  std::vector<std::shared_ptr<const Material>> slots{make_deck_material(cfg)};
  for (const MaterialConfig& m : cfg.material_regions)
    slots.push_back(build_material(m, cfg.source));
  return MaterialSet(std::move(slots));
}

void assign_material_slots(const Config& cfg, const MaterialSet& materials,
                           std::int64_t lattice_count, const std::vector<int>& splat_part,
                           Particles& p) {
  if (cfg.material_regions.empty()) return;
  // The non-splat parts' shapes, only when an entry names a part.
  const bool by_part = std::any_of(cfg.material_regions.begin(), cfg.material_regions.end(),
                                   [](const MaterialConfig& m) { return !m.has_region; });
  std::vector<std::pair<int, std::unique_ptr<geometry::Shape>>> solids;
  if (by_part)
    for (std::size_t g = 0; g < cfg.geometry.size(); ++g)
      if (cfg.geometry[g].type != "splats")
        solids.emplace_back(static_cast<int>(g), geometry::make_shape({cfg.geometry[g]}));
  std::vector<std::array<double, kStateSize>> init(materials.size());
  for (std::size_t s = 0; s < materials.size(); ++s) materials[s].init_state(init[s].data());
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec3d x{p.x[3 * i], p.x[3 * i + 1], p.x[3 * i + 2]};
    int part = -1;
    if (p.id[i] >= lattice_count) {
      part = splat_part.at(static_cast<std::size_t>(p.id[i] - lattice_count));
    } else {
      const Eigen::Vector3d xe(x[0], x[1], x[2]);
      for (const auto& [g, shape] : solids)
        if (shape->inside(xe)) {
          part = g;
          break;
        }
    }
    const int slot = material_slot(cfg, part, x);
    p.material[i] = static_cast<std::uint8_t>(slot);
    if (slot == 0) continue;
    p.mass[i] = materials[static_cast<std::size_t>(slot)].density() * p.vol0[i];
    std::copy_n(init[static_cast<std::size_t>(slot)].data(), kStateSize, &p.state[kStateSize * i]);
  }
}

MpmSimulation::MpmSimulation(MPI_Comm comm, const Config& cfg, bool seed) : comm_(comm), cfg_(cfg) {
  rank_ = parallel::rank(comm);
  size_ = parallel::size(comm);
  const MaterialSet materials = make_deck_materials(cfg_);
  // Splat parts become one particle per Gaussian; the others are seeded on the lattice.
  std::vector<GeometryConfig> solid_parts;
  gaussians::SplatSet splats;
  std::vector<int> splat_part;  // Config::geometry index of each splat
  bool any_splats = false;
  for (const GeometryConfig& g : cfg_.geometry) {
    if (g.type == "splats") {
      gaussians::append_splats(splats, gaussians::load_geometry_splats(g));
      splat_part.resize(splats.size(), static_cast<int>(&g - cfg_.geometry.data()));
      any_splats = true;
    } else {
      solid_parts.push_back(g);
    }
  }
  std::unique_ptr<geometry::Shape> shape;
  geometry::Aabb bounds;
  if (!solid_parts.empty()) {
    shape = geometry::make_shape(solid_parts);
    bounds = shape->bounds();
  }
  for (std::size_t i = 0; i < splats.size(); ++i)
    bounds.extend(Eigen::Vector3d(splats.position[3 * i], splats.position[3 * i + 1],
                                  splats.position[3 * i + 2]));
  spec_ = layout_grid(cfg_, bounds);
  carries_splats_ = any_splats || cfg_.render.enabled;
  layout_.sh_degree = splats.sh_degree;
  kinematics_ = gaussians::KinematicsOptions::parse(cfg_.render.kinematics,
                                                    cfg_.source + ": key 'render.kinematics'");
  covariance_update_ = parse_covariance_update(cfg_.render.covariance_update,
                                               cfg_.source + ": key 'render.covariance_update'");
  if (cfg_.render.enabled) {
    renderer_ = std::make_unique<gaussians::RunRenderer>(comm_, cfg_.render);
    const geometry::Aabb other = shape ? shape->bounds() : geometry::Aabb();
    renderer_->frame_object(splats, {other.lo[0], other.lo[1], other.lo[2]},
                            {other.hi[0], other.hi[1], other.hi[2]});
  }
  const SolverOptions opt = solver_options(cfg_);
  solver_ = std::make_unique<Solver>(comm_, spec_, materials, opt, boundary_conditions(cfg_));
  const double limit = spec_.dx / std::max(materials.wave_speed(), 1e-300);
  if (rank_ == 0 && !opt.adaptive && cfg_.dt > limit)
    log::warn(
        "mpm.substep = \"fixed\": simulation.dt = {:.3g} s is {:.1f}x the elastic stability "
        "limit dx / c = {:.3g} s; the instability guard will stop the run if it blows up",
        cfg_.dt, cfg_.dt / limit, limit);
  if (!seed) return;
  const int ppa = cfg_.mpm.particles_per_axis;
  Particles p;
  if (shape) p = seed_particles(comm_, spec_, *shape, ppa, materials[0], cfg_.mpm.velocity);
  if (carries_splats_) add_lattice_splats(p, layout_, cfg_, solid_parts, spec_.dx / ppa);
  long long n = parallel::sum_of(comm_, static_cast<long long>(p.size()));
  const long long lattice_count = n;
  if (splats.size() > 0) {
    // Ids after the lattice particles', in the deck's splat order.
    p.append(seed_splats(comm_, spec_, splats, materials[0], cfg_.mpm.velocity, n,
                         layout_.sh_degree, cfg_.source));
    n += static_cast<long long>(splats.size());
  }
  if (n == 0)
    throw InputError(cfg_.source +
                     ": the geometry holds no particle of the MPM grid (is the object inside "
                     "[mpm] lo/hi, and larger than domain.voxel_size / particles_per_axis?)");
  total_ = n;
  assign_material_slots(cfg_, materials, lattice_count, splat_part, p);
  add_point_masses(comm_, cfg_.point_masses, p);
  solver_->distribute(std::move(p));
  const long long local = static_cast<long long>(solver_->particles().size());
  const long long most = parallel::max_of(comm_, local), least = parallel::min_of(comm_, local);
  if (size_ > 1)
    log::info("mpm: static balance over {} ranks: {} to {} particles per rank (max / mean {:.3f})",
              size_, least, most, static_cast<double>(most) * size_ / static_cast<double>(n));
  log::info("mpm: {} particles ({} per cell{}), grid {} x {} x {} cells of {:.4g} m, material {}",
            total_, ppa * ppa * ppa,
            (splats.size() == 0) ? std::string() : fmt::format("; {} from splats", splats.size()),
            spec_.cells[0], spec_.cells[1], spec_.cells[2], spec_.dx, materials.describe());
}

MpmSimulation::~MpmSimulation() = default;

double MpmSimulation::frame_interval() const {
  return cfg_.output.frame_interval > 0 ? cfg_.output.frame_interval : cfg_.dt;
}

void MpmSimulation::load_checkpoint(const std::string& path) {
  Particles p;
  const ParticleCheckpointMeta meta = read_particle_checkpoint(comm_, path, p);
  total_ = meta.total_particles;
  step_ = meta.step;
  time_ = meta.time;
  frame_index_ = meta.frame_index;
  next_frame_time_ = meta.next_frame_time;
  auto get = [&](const char* k) {
    auto it = meta.extras.find(k);
    return it == meta.extras.end() ? 0.0 : it->second;
  };
  solver_->set_counters(static_cast<long long>(get("removed")),
                        static_cast<long long>(get("clamped")));
  carries_splats_ = !meta.extra_names.empty();
  if (carries_splats_) layout_ = SplatLayout::from_names(meta.extra_names, path);
  if (cfg_.render.enabled && !carries_splats_)
    throw InputError(path +
                     ": the checkpoint holds no splat attributes to render ([render] "
                     "needs a checkpoint of a run with [render] or splat geometry)");
  solver_->distribute(std::move(p));
  log::info("restart from {}: substep {}, t = {:.6g} s, {} particles alive", path, step_, time_,
            solver_->count());
}

std::string MpmSimulation::write_checkpoint(const std::string& out_dir, const Snapshot* from) {
  const auto t0 = std::chrono::steady_clock::now();
  ParticleCheckpointState st;
  st.step = static_cast<int>(from ? from->step : step_);
  st.time = from ? from->time : time_;
  st.frame_index = static_cast<int>(from ? from->frame_index : frame_index_);
  st.next_frame_time = from ? from->next_frame_time : next_frame_time_;
  st.deck_text = cfg_.text;
  st.total_particles = total_;
  st.state_names = solver_->materials().state_names();
  if (carries_splats_) st.extra_names = layout_.names();
  st.extras["removed"] = static_cast<double>(solver_->removed());
  st.extras["clamped"] = static_cast<double>(solver_->clamped());
  st.particles = from ? &from->particles : &solver_->particles();
  const std::string path =
      write_particle_checkpoint(comm_, out_dir, st, cfg_.output.checkpoint_keep);
  io_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return path;
}

void MpmSimulation::write_frame(ParticleFrameWriter& writer, const std::string& out_dir) {
  const auto t0 = std::chrono::steady_clock::now();
  const Particles& p = solver_->particles();
  const std::size_t n = p.size();
  // Output fields: J = det F, the material's state slots, von Mises of the Cauchy stress.
  std::vector<double> J(n), mises(n), tau(9 * n);
  const MaterialSet& materials = solver_->materials();
  if (n) materials.stress(n, p.material.data(), p.F.data(), p.state.data(), tau.data());
  const auto names = materials.state_names();
  std::vector<std::vector<double>> slots(names.size(), std::vector<double>(n));
  for (std::size_t i = 0; i < n; ++i) {
    const double* F = &p.F[9 * i];
    J[i] = F[0] * (F[4] * F[8] - F[5] * F[7]) - F[1] * (F[3] * F[8] - F[5] * F[6]) +
           F[2] * (F[3] * F[7] - F[4] * F[6]);
    mises[i] = materials::mises(&tau[9 * i]) / std::max(J[i], 1e-12);
    for (std::size_t s = 0; s < names.size(); ++s) slots[s][i] = p.state[kStateSize * i + s];
  }
  std::vector<ParticleScalar> fields{{"J", J.data()}, {"von_mises_stress", mises.data()}};
  for (std::size_t s = 0; s < names.size(); ++s) fields.push_back({names[s], slots[s].data()});
  std::vector<double> slot(materials.size() > 1 ? n : 0);
  for (std::size_t i = 0; i < slot.size(); ++i) slot[i] = p.material[i];
  if (materials.size() > 1) fields.push_back({"material", slot.data()});
  writer.write_frame(time_, static_cast<int>(step_), p, fields);
  const int index = static_cast<int>(writer.frames().back().index);
  check_walls();
  if (cfg_.output.particles == "ply")
    write_particle_ply(
        comm_,
        (fs::path(out_dir) / "particles" / fmt::format("particles_{:06d}.ply", index)).string(), p);
  if (cfg_.output.volumes == "vdb")
    write_particle_vdb(
        comm_, (fs::path(out_dir) / "volumes" / fmt::format("volume_{:06d}.vdb", index)).string(),
        p, spec_.dx);
  if (cfg_.output.particles == "ply" && carries_splats_) {
    const gaussians::SplatSet deformed =
        gather_deformed_splats(comm_, p, layout_, kinematics_, covariance_update_);
    std::string error;
    if (rank_ == 0) {
      try {
        gaussians::write_splats_ply(
            (fs::path(out_dir) / "splats" / fmt::format("splats_{:06d}.ply", index)).string(),
            deformed);
      } catch (const std::exception& e) {
        error = e.what();
      }
    }
    error = io::h5::first_error(comm_, error);
    if (!error.empty()) throw RuntimeError(error);
  }
  io_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (renderer_) render_frame(index);
}

void MpmSimulation::check_walls() {
  // The walls act unless a bounding_box entry (the last one) is inactive now.
  bool walls = true;
  for (const BoundaryConfig& b : cfg_.boundaries)
    if (b.type == "bounding_box") walls = time_ >= b.start && time_ < b.end;
  const WallCount count =
      particles_at_walls(comm_, spec_, walls ? cfg_.mpm.boundary_layers : 0, solver_->particles());
  at_walls_ = count.particles;
  if (at_walls_ == 0 || walls_warned_) return;
  walls_warned_ = true;
  log::info(
      "warning: t = {:.6g} s: {} particle(s) touch the grid walls (mpm.boundary_layers = {}; "
      "{}), which stop their motion out of the grid; enlarge [mpm] lo/hi or domain.padding "
      "if the walls are not meant to be part of the scene",
      time_, at_walls_, cfg_.mpm.boundary_layers, describe_walls(count.per_wall));
}

void MpmSimulation::render_frame(int index) {
  PhaseTimers::Scope scope(solver_->timers(), "render");
  renderer_->render(index,
                    splat_frame(solver_->particles(), layout_, kinematics_, covariance_update_));
}

void MpmSimulation::take_snapshot() {
  snapshot_.particles = solver_->particles();
  snapshot_.step = step_;
  snapshot_.time = time_;
  snapshot_.frame_index = frame_index_;
  snapshot_.next_frame_time = next_frame_time_;
}

MpmRunResult MpmSimulation::run(const std::string& out_dir, bool append) {
  MpmRunResult res;
  // Output folders (rank 0 creates; a failure reaches every rank).
  std::string error;
  if (rank_ == 0) {
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (!ec && cfg_.output.particles == "ply")
      fs::create_directories(fs::path(out_dir) / "particles", ec);
    if (!ec && cfg_.output.volumes == "vdb")
      fs::create_directories(fs::path(out_dir) / "volumes", ec);
    if (!ec && cfg_.output.particles == "ply" && carries_splats_)
      fs::create_directories(fs::path(out_dir) / "splats", ec);
    if (ec) error = out_dir + ": cannot create the output directory: " + ec.message();
  }
  error = io::h5::first_error(comm_, error);
  if (!error.empty()) throw RuntimeError(error);
  const std::string frames_path = (fs::path(out_dir) / "particles.h5").string();
  ParticleFrameWriter writer =
      append ? ParticleFrameWriter::open_append(comm_, frames_path, static_cast<int>(step_))
             : ParticleFrameWriter(comm_, frames_path, total_,
                                   {{"deck", cfg_.text}, {"solver", "mpm"}});
  const double interval = frame_interval();
  if (renderer_) {
    PhaseTimers::Scope scope(solver_->timers(), "render");
    // Images after the last frame kept belong to a run that particles.h5 no longer holds.
    renderer_->open(out_dir, writer.frames().empty() ? -1 : writer.frames().back().index);
  }
  if (!append) {
    // A fresh file starts with the current state (t = 0, or a restart's checkpoint).
    write_frame(writer, out_dir);
    if (step_ == 0) {
      frame_index_ = 1;
      next_frame_time_ = interval;
    }
  }
  take_snapshot();
  const double end = cfg_.end_time;
  const auto start = std::chrono::steady_clock::now();
  auto last_print = start;
  const double t_start = time_;
  long substeps = 0;
  while (time_ < end * (1 - 1e-12)) {
    // A frame time within a billionth of a frame past the end is the last frame (0.02 x 30 is
    // 0.6000000000000001).
    const double target = next_frame_time_ <= end + 1e-9 * interval ? next_frame_time_ : end;
    double dt = solver_->stable_dt(target - time_);
    // A substep that would leave less than a millionth of itself before the target reaches it:
    // the rounding of t + dt would otherwise cost an extra, vanishing substep per frame.
    if (dt < target - time_ && target - time_ - dt <= 1e-6 * dt) dt = target - time_;
    const bool reaches = dt >= (target - time_) * (1 - 1e-12);
    try {
      solver_->substep(time_, dt);
      if (carries_splats_) {
        PhaseTimers::Scope scope(solver_->timers(), "splats");
        advance_splats(solver_->particles(), layout_, dt, covariance_update_);
      }
    } catch (const InstabilityError& e) {
      const std::string path = write_checkpoint(out_dir, &snapshot_);
      writer.close();
      throw RuntimeError(fmt::format("{}. The last good frame (t = {:.6g} s) is in {}", e.what(),
                                     snapshot_.time, path));
    }
    time_ = reaches ? target : time_ + dt;
    ++step_;
    ++substeps;
    if (reaches && target == next_frame_time_) {
      write_frame(writer, out_dir);
      ++frame_index_;
      next_frame_time_ = interval * static_cast<double>(frame_index_);
      take_snapshot();
    } else if (reaches && time_ >= end) {
      write_frame(writer, out_dir);  // the final state, between two frame times
      take_snapshot();
    }
    const bool periodic =
        cfg_.output.checkpoint_every > 0 && step_ % cfg_.output.checkpoint_every == 0;
    const int sig = (substeps % 16 == 0 || periodic) ? signals::pending(comm_) : 0;
    if (periodic || sig) res.last_checkpoint = write_checkpoint(out_dir);
    if (sig) {
      // SIGUSR1: checkpoint and go on; SIGTERM: checkpoint and stop (as the voxel solver).
      log::info("received {}: checkpoint {} written at substep {}, t = {:.6g} s{}",
                sig == SIGTERM ? "SIGTERM" : "SIGUSR1", res.last_checkpoint, step_, time_,
                sig == SIGTERM ? "; stopping" : "");
      if (sig == SIGTERM) {
        res.exit_code = 1;
        break;
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_print).count() >= cfg_.output.progress_interval ||
        time_ >= end * (1 - 1e-12)) {
      last_print = now;
      const double wall = std::chrono::duration<double>(now - start).count();
      const double rate = (time_ - t_start) / std::max(wall, 1e-9);
      log::info(
          "substep {:>7}  t = {:.5g} s ({:.1f} %)  dt {:.3g} s  {:.1f} substeps/s  ETA {}"
          "  removed {}  clamped {}  at walls {}",
          step_, time_, 100 * time_ / end, dt, static_cast<double>(substeps) / std::max(wall, 1e-9),
          ProgressLog::format_duration((end - time_) / std::max(rate, 1e-300)), solver_->removed(),
          solver_->clamped(), at_walls_);
    }
  }
  if (res.exit_code == 0) res.last_checkpoint = write_checkpoint(out_dir);
  writer.close();
  if (renderer_ && res.exit_code == 0) {
    PhaseTimers::Scope scope(solver_->timers(), "render");
    renderer_->finish(interval);
  }
  res.substeps = substeps;
  res.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report_timers(res.wall_seconds, substeps);
  if (solver_->removed() || solver_->clamped())
    log::info("particles that left the grid: {} removed, {} clamped back in", solver_->removed(),
              solver_->clamped());
  if (at_walls_ > 0)
    log::info("particles touching the grid walls at the last frame: {}", at_walls_);
  return res;
}

void MpmSimulation::report_timers(double wall, long substeps) const {
  std::vector<const char*> phases = {"material", "p2g",   "halo",     "grid",
                                     "g2p",      "guard", "migration"};
  if (carries_splats_) phases.push_back("splats");
  if (cfg_.render.enabled) phases.push_back("render");
  double n = static_cast<double>(solver_->count()) * static_cast<double>(substeps);
  log::info("phase timers (max over ranks, wall {:.2f} s, {:.3g} particle-substeps/s):", wall,
            n / std::max(wall, 1e-9));
  const auto& timers = solver_->timers();
  for (const char* p : phases) {
    const double global = parallel::max_of(comm_, timers.total(p));
    log::info("  {:<10} {:9.3f} s  {:5.1f} %", p, global, 100.0 * global / std::max(wall, 1e-9));
  }
  const double gio = parallel::max_of(comm_, io_seconds_);
  log::info("  {:<10} {:9.3f} s  {:5.1f} %", "io", gio, 100.0 * gio / std::max(wall, 1e-9));
}

}  // namespace gen4d::mpm
