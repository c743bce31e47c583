//! Helpers the diagnose tests share: effects set on a Physics by their term values
//! (Effect::apply's, without a scene context), the StVK beams they diagnose, and noisy
//! marker recordings of a model's runs.
#pragma once

#include <gtest/gtest.h>
#include <mpi.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "deck_test_util.hpp"
#include "diagnose/Effects.hpp"
#include "diagnose/Fit.hpp"
#include "diagnose/Forward.hpp"
#include "diagnose/Recording.hpp"

namespace gen4d::diagnose::testing {

//! E times `factor` in `box`.
inline void set_region(Physics& p, const BoxRegion& box, double factor) {
  set_effect_terms(p, "heterogeneity",
                   {factor, box.lo[0], box.lo[1], box.lo[2], box.hi[0], box.hi[1], box.hi[2]});
}
//! Removes the effect called `name` from p.
inline void clear_effect(Physics& p, const std::string& name) {
  set_effect_terms(p, name, find_effect(name).absent_terms());
}

//! A StVK box [0, hi] of modulus E (nu 0.3, 1000 kg/m^3) on 0.01 m voxels, run with `dt` to
//! `end_time`; `simulation`: more [simulation] keys (name, gravity). Loads and clamps follow.
//! `domain`: more [domain] keys (padding).
inline test::TestDeck stvk_box(double dt, double end_time, const test::Keys& simulation,
                               const Vec3d& hi, double youngs_modulus,
                               const test::Keys& domain = {}) {
  return test::TestDeck()
      .simulation(dt, end_time, simulation)
      .domain(0.01, domain)
      .box({0, 0, 0}, hi)
      .material(youngs_modulus, 0.3, 1000, {{"model", test::quoted("stvk")}});
}

//! [simulation] keys: the run's name and gravity (0, 0, gz).
inline test::Keys named(const std::string& name, double gz) {
  return {{"name", test::quoted(name)}, {"gravity", test::toml(Vec3d{0, 0, gz})}};
}

//! [[force]] keys: `force` from t = 0 to `end`.
inline test::Keys pulse(const Vec3d& force, double end) {
  return {{"force", test::toml(force)}, {"start", "0"}, {"end", test::toml(end)}};
}

//! The diagnose tests' cantilever: stvk_box clamped at x = 0 and loaded on x >= tip_x (`load`:
//! [[force]] keys).
inline std::string cantilever(const test::Keys& simulation, double dt, double end_time,
                              const Vec3d& hi, double youngs_modulus, double tip_x,
                              const test::Keys& load) {
  return stvk_box(dt, end_time, simulation, hi, youngs_modulus)
      .clamp()
      .region("force", {tip_x, -1, -1}, {1, 1, 1}, load);
}

//! Position requests at `markers`, sampled at k * dt for k = 0..n.
inline std::vector<ChannelRequest> marker_requests(const ForwardModel& m,
                                                   const std::vector<Vec3d>& markers, int n,
                                                   double dt) {
  std::vector<ChannelRequest> req;
  for (const Vec3d& X : markers) {
    ChannelRequest q;
    q.at = m.attach(X);
    for (int k = 0; k <= n; ++k) q.t.push_back(dt * k);
    req.push_back(q);
  }
  return req;
}

//! Marker channels at `markers` (ids prefix + index) with the run's positions plus Gaussian
//! noise of sd `sd` (seeded), drawn x, y, z per sample.
inline Recording noisy_markers(const std::vector<Vec3d>& markers,
                               const std::vector<ChannelRequest>& req, const Trace& tr, double sd,
                               unsigned seed, const std::string& prefix = "m") {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, sd);
  Recording rec;
  for (std::size_t c = 0; c < req.size(); ++c) {
    Channel ch;
    ch.kind = ChannelKind::Position;
    ch.id = prefix + std::to_string(c);
    ch.X = {markers[c][0], markers[c][1], markers[c][2]};
    for (std::size_t k = 0; k < req[c].t.size(); ++k) {
      ch.t.push_back(req[c].t[k]);
      ch.value.push_back({tr.channel[c][3 * k] + noise(rng), tr.channel[c][3 * k + 1] + noise(rng),
                          tr.channel[c][3 * k + 2] + noise(rng)});
    }
    rec.channels.push_back(ch);
  }
  return rec;
}

//! The scene an effect sets its parameters in: model m, baseline `base`, motion at `omega`
//! rad/s, peak von Mises stress `max_mises`.
inline EffectContext effect_context(const ForwardModel& m, const Physics& base, double omega,
                                    double max_mises = 0) {
  EffectContext ctx;
  ctx.model = &m;
  ctx.base = base;
  ctx.omega = omega;
  ctx.max_mises = max_mises;
  return ctx;
}

//! Observations of every sample of obs.requests, all fitted, of noise `sigma`: the values of
//! run `tr`, or 0 without one.
inline void add_fitted(Observations& obs, double sigma, const Trace* tr = nullptr) {
  for (std::size_t c = 0; c < obs.requests.size(); ++c)
    for (std::size_t k = 0; k < obs.requests[c].t.size(); ++k)
      for (int d = 0; d < 3; ++d) {
        obs.y.push_back(tr ? tr->channel[c][3 * k + static_cast<std::size_t>(d)] : 0.0);
        obs.t.push_back(obs.requests[c].t[k]);
        obs.channel.push_back(static_cast<int>(c));
        obs.component.push_back(d);
        obs.sigma.push_back(sigma);
        obs.train.push_back(1);
        obs.heldout.push_back(0);
      }
}

//! The message of the InputError `f` throws; a failure naming `what` (and "") when it throws
//! none.
template <class F>
std::string refusal(const F& f, const std::string& what) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << what << " was accepted";
  return "";
}

//! The whole text of a file (a report.json).
inline std::string file_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

//! Writes rec as dir/rec.csv on rank 0 (dir made afresh); every rank waits for it.
inline void write_fresh_recording(const Recording& rec, const std::string& dir) {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank == 0) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    write_recording_csv(rec, dir + "/rec.csv");
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

}  // namespace gen4d::diagnose::testing
