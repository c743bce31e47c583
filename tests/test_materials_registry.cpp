// The one law vocabulary (materials/Registry.hpp): every law of the table resolves, and is
// implemented, for exactly the solvers the table gives it; old spellings warn once and resolve
// to the same law; unknown names list the known ones; the example decks' names resolve.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <toml++/toml.h>

#include "core/Error.hpp"
#include "materials/Registry.hpp"
#include "mpm/Material.hpp"

namespace gm = gen4d::materials;
namespace mpm = gen4d::mpm;
using gm::Mat3;
using gm::Solver;

namespace {

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

//! The MPM model `name` with E = 1e6, nu = 0.3, rho = 1000 and the keys its kind requires.
std::unique_ptr<mpm::Material> mpm_model(const std::string& name) {
  mpm::MaterialParams p;
  p.model = name;
  p.values = {{"youngs_modulus", 1e6}, {"poisson_ratio", 0.3}, {"density", 1000}};
  if (name == "drucker_prager") p.values["friction_angle"] = 30;
  if (name == "von_mises") p.values["yield_stress"] = 1e4;
  if (name == "herschel_bulkley") p.values["yield_stress"] = 1e3, p.values["consistency"] = 1;
  if (name == "fracture") p.values["fracture_strain"] = 0.1, p.values["failure_strain"] = 0.2;
  return mpm::make_material(p);
}

std::string input_error(const std::function<void()>& f) {
  try {
    f();
  } catch (const gen4d::InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

}  // namespace

TEST(LawVocabulary, TheTableNamesEachEnergyOnce) {
  const std::vector<std::string> expected = {"arap",
                                             "drucker_prager",
                                             "fixed_corotated",
                                             "fracture",
                                             "herschel_bulkley",
                                             "linear",
                                             "neo_hookean",
                                             "snow",
                                             "stable_neo_hookean",
                                             "stvk",
                                             "stvk_hencky",
                                             "von_mises"};
  std::vector<std::string> names;
  for (const gm::LawInfo& law : gm::laws())
    if (law.energy != "(registered by the program)") names.push_back(law.name);
  EXPECT_EQ(names, expected);
  for (const gm::LawInfo& law : gm::laws()) {
    EXPECT_FALSE(law.energy.empty()) << law.name;
    EXPECT_TRUE(law.voxel || law.mpm) << law.name;
  }
}

TEST(LawVocabulary, EveryLawResolvesAndIsBuiltForTheSolversThatOfferIt) {
  const Mat3 F = gm::diag3(gm::Vec3{{1.1, 0.95, 0.9}});
  for (const gm::LawInfo& law : gm::laws()) {
    if (law.energy == "(registered by the program)") continue;
    for (const Solver s : {Solver::Voxel, Solver::Mpm}) {
      const bool offered = s == Solver::Voxel ? law.voxel : law.mpm;
      if (offered) {
        EXPECT_EQ(gm::canonical_law(law.name, s), law.name);
        EXPECT_TRUE(contains(gm::law_names(s), law.name)) << law.name;
        EXPECT_EQ(gm::deprecation(law.name, s), "") << law.name;
      } else if (gm::deprecation(law.name, s).empty()) {
        EXPECT_THROW(gm::canonical_law(law.name, s), gen4d::InputError) << law.name;
      }
    }
    if (law.voxel) {
      const gm::MaterialInstance m = gm::find_material(law.name).build(1e6, 0.3);
      EXPECT_EQ(m.name, law.name);
      EXPECT_GT(m.energy(F), 0) << law.name;
    }
    if (law.mpm) EXPECT_EQ(mpm_model(law.name)->name(), law.name);
  }
}

TEST(LawVocabulary, OldSpellingsWarnOnceAndResolveToTheSameLaw) {
  EXPECT_EQ(gm::canonical_law("corotated", Solver::Voxel), "fixed_corotated");
  EXPECT_EQ(gm::canonical_law("corotated", Solver::Mpm), "fixed_corotated");
  EXPECT_EQ(gm::canonical_law("neo_hookean", Solver::Voxel), "stable_neo_hookean");
  EXPECT_EQ(gm::canonical_law("neo_hookean", Solver::Mpm), "neo_hookean");  // log J
  EXPECT_EQ(gm::deprecation("neo_hookean", Solver::Mpm), "");

  const std::string message = gm::deprecation("neo_hookean", Solver::Voxel);
  EXPECT_NE(message.find("'stable_neo_hookean'"), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  testing::internal::CaptureStderr();
  EXPECT_EQ(gm::resolve_law("neo_hookean", Solver::Voxel, "deck.toml:7: material.model"),
            "stable_neo_hookean");
  EXPECT_EQ(gm::resolve_law("neo_hookean", Solver::Voxel, "deck.toml:7: material.model"),
            "stable_neo_hookean");
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("deck.toml:7: material.model: " + message), std::string::npos) << said;
  EXPECT_EQ(std::count(said.begin(), said.end(), '\n'), 1) << said;  // once, one line

  // The same law, bit for bit, under the name it was asked for.
  const Mat3 F = gm::diag3(gm::Vec3{{1.2, 0.9, -0.7}});
  for (const auto& [old_name, law] : std::vector<std::pair<std::string, std::string>>{
           {"corotated", "fixed_corotated"}, {"neo_hookean", "stable_neo_hookean"}}) {
    const gm::MaterialInstance a = gm::find_material(old_name).build(1e6, 0.3);
    const gm::MaterialInstance b = gm::find_material(law).build(1e6, 0.3);
    EXPECT_EQ(a.name, old_name);
    EXPECT_EQ(a.energy(F), b.energy(F)) << old_name;
    EXPECT_EQ(gm::frobenius_norm(a.pk1(F) - b.pk1(F)), 0.0) << old_name;
    EXPECT_EQ(a.projection_stiffness, b.projection_stiffness) << old_name;
  }
  EXPECT_EQ(mpm_model("corotated")->name(), "fixed_corotated");
}

TEST(LawVocabulary, UnknownNamesListTheSolversLaws) {
  const std::string voxel =
      input_error([] { gm::canonical_law("drucker_prager", Solver::Voxel, "d.toml:3"); });
  EXPECT_NE(voxel.find("d.toml:3: unknown material 'drucker_prager'"), std::string::npos);
  EXPECT_NE(voxel.find("fixed_corotated"), std::string::npos) << voxel;
  EXPECT_NE(voxel.find("stable_neo_hookean"), std::string::npos) << voxel;
  EXPECT_EQ(voxel.find("von_mises"), std::string::npos) << voxel;
  const std::string mpm_msg = input_error([] { gm::canonical_law("stvk", Solver::Mpm); });
  EXPECT_NE(mpm_msg.find("known: "), std::string::npos) << mpm_msg;
  EXPECT_NE(mpm_msg.find("stvk_hencky"), std::string::npos) << mpm_msg;
  EXPECT_EQ(mpm_msg.find("stable_neo_hookean"), std::string::npos) << mpm_msg;
  EXPECT_EQ(mpm_msg.find('\n'), std::string::npos) << mpm_msg;
}

TEST(LawVocabulary, TheExampleDecksNamesResolve) {
  int decks = 0;
  for (const auto& entry : std::filesystem::directory_iterator(GEN4D_SOURCE_DIR "/inputs")) {
    if (entry.path().extension() != ".toml") continue;
    const toml::table deck = toml::parse_file(entry.path().string());
    const Solver s = deck["solver"]["method"].value_or(std::string("elastogen")) == "mpm"
                         ? Solver::Mpm
                         : Solver::Voxel;
    std::vector<std::string> models;
    if (auto m = deck["material"]["model"].value<std::string>()) models.push_back(*m);
    if (const toml::array* list = deck["material"].as_array())
      for (const auto& t : *list)
        if (auto m = t.as_table()->get_as<std::string>("model")) models.push_back(m->get());
    for (const std::string& m : models) {
      EXPECT_NO_THROW(gm::canonical_law(m, s)) << entry.path() << ": " << m;
      ++decks;
    }
  }
  EXPECT_GE(decks, 5);
}
