// Weight dataset, autoencoder and latent DDPM of the NeuralMTL generator (seed App. B).
//
// Sizes against the seed's Table 3 (AE 8192..256 FC, latent 256, Conv2D U-Net denoiser):
// our networks have 771 parameters (3-24-24-3), not ~8k, and the dataset is 75 networks
// lying on three smooth curves (one per law, parameterised by nu), so a 771-128-64 FC encoder
// (mirror decoder) and a 64-dimensional latent already reconstruct them to ~2 % of their
// spread per weight (energy correlation >= 0.9999 after the round trip), and the whole generator
// stays under 3 MB in float64. The denoiser is an MLP on [z_t, sinusoidal embedding of t,
// condition] rather than the seed's 2D conv net: the latent vector has no spatial structure for
// convolutions to exploit (the seed views it as a 1-channel image only to reuse an image U-Net),
// and an MLP of width 192 fits the delta-like conditional distribution (one network per condition)
// in a few minutes of CPU time.
#include "neural_train/Generator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "neural/ArrayFile.hpp"
#include "neural_train/TorchCommon.hpp"
#include "neural_train/Train.hpp"

namespace gen4d::neural_train {

using detail::f64;

namespace {

constexpr int kTimeDim = 32;  // sinusoidal time embedding
constexpr int kNuHarmonics = 3;
constexpr int kCondDim = 3 + 1 + 2 * kNuHarmonics;  // law one-hot, nu, Fourier features of nu

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

std::string join_hidden(const std::vector<int>& h) {
  std::string s;
  for (std::size_t i = 0; i < h.size(); ++i) s += (i ? "," : "") + std::to_string(h[i]);
  return s;
}

// A plain MLP with SiLU between layers and none after the last.
struct Net {
  std::vector<torch::Tensor> W, b;

  static Net random(const std::vector<int>& sizes, at::Generator& gen) {
    Net n;
    for (std::size_t l = 0; l + 1 < sizes.size(); ++l) {
      const double scale = std::sqrt(1.0 / sizes[l]);
      n.W.push_back(
          (torch::randn({sizes[l + 1], sizes[l]}, gen, f64()) * scale).set_requires_grad(true));
      n.b.push_back(torch::zeros({sizes[l + 1]}, f64()).set_requires_grad(true));
    }
    return n;
  }
  torch::Tensor forward(torch::Tensor h) const {
    for (std::size_t l = 0; l < W.size(); ++l) {
      h = torch::addmm(b[l], h, W[l].t());
      if (l + 1 < W.size()) h = torch::silu(h);
    }
    return h;
  }
  std::vector<torch::Tensor> parameters() const { return detail::layer_parameters(W, b); }
  std::size_t values() const {
    std::size_t n = 0;
    for (auto& p : parameters()) n += static_cast<std::size_t>(p.numel());
    return n;
  }
  void store(neural::ArrayFile& f, const std::string& prefix) const {
    for (std::size_t l = 0; l < W.size(); ++l) {
      const std::string p = prefix + std::to_string(l);
      f.arrays[p + "_W"] =
          neural::NamedArray{{W[l].size(0), W[l].size(1)}, detail::to_vector(W[l])};
      f.arrays[p + "_b"] = neural::NamedArray{{b[l].size(0)}, detail::to_vector(b[l])};
    }
  }
  static Net load(const neural::ArrayFile& f, const std::string& prefix,
                  const std::vector<int>& sizes, const std::string& file) {
    Net n;
    for (std::size_t l = 0; l + 1 < sizes.size(); ++l) {
      const std::string p = prefix + std::to_string(l);
      const auto& W = f.array(p + "_W", {sizes[l + 1], sizes[l]}, file);
      const auto& b = f.array(p + "_b", {sizes[l + 1]}, file);
      n.W.push_back(detail::from_vector(W.data, sizes[l + 1], sizes[l]));
      n.b.push_back(detail::from_vector(b.data, 1, sizes[l + 1]).reshape({sizes[l + 1]}));
    }
    return n;
  }
};

torch::Tensor time_embedding(const torch::Tensor& t) {  // t: (B) float64
  const int half = kTimeDim / 2;
  torch::Tensor k = torch::arange(half, f64());
  torch::Tensor freq = torch::exp(-std::log(1000.0) * k / half);
  torch::Tensor a = t.unsqueeze(1) * freq.unsqueeze(0);
  return torch::cat({torch::sin(a), torch::cos(a)}, 1);
}

torch::Tensor conditions(const std::vector<int>& law, const std::vector<double>& nu) {
  const long n = static_cast<long>(nu.size());
  torch::Tensor c = torch::zeros({n, kCondDim}, f64());
  auto acc = c.accessor<double, 2>();
  for (long i = 0; i < n; ++i) {
    acc[i][law[static_cast<std::size_t>(i)]] = 1.0;
    const double x = nu[static_cast<std::size_t>(i)];
    acc[i][3] = x / 0.25 - 1.0;
    for (int k = 1; k <= kNuHarmonics; ++k) {
      acc[i][3 + 2 * k - 1] = std::sin(M_PI * k * x / 0.5);
      acc[i][3 + 2 * k] = std::cos(M_PI * k * x / 0.5);
    }
  }
  return c;
}

// Cosine schedule (Nichol & Dhariwal 2021): alpha_bar(t) = cos^2(((t/T + s)/(1 + s)) pi/2).
std::vector<double> cosine_betas(int T) {
  auto ab = [&](double t) {
    const double s = 0.008;
    const double c = std::cos((t / T + s) / (1 + s) * M_PI / 2);
    return c * c;
  };
  std::vector<double> b(static_cast<std::size_t>(T));
  for (int t = 0; t < T; ++t)
    b[static_cast<std::size_t>(t)] = std::min(1 - ab(t + 1) / ab(t), 0.999);
  return b;
}

void set_lr(torch::optim::Adam& opt, double lr) {
  for (auto& g : opt.param_groups()) static_cast<torch::optim::AdamOptions&>(g.options()).lr(lr);
}
double cosine_lr(double lr0, int it, int total) {
  return lr0 * (0.02 + 0.98 * 0.5 * (1 + std::cos(M_PI * it / std::max(1, total))));
}

}  // namespace

// -------------------------------------------------------------------------------------------
// Dataset

std::vector<std::pair<int, double>> dataset_chain(int nu_count, double nu_max) {
  std::vector<double> nus;
  for (int i = 0; i < nu_count; ++i) nus.push_back(nu_max * i / std::max(1, nu_count - 1));
  std::vector<std::pair<int, double>> chain;
  for (double v : nus) chain.emplace_back(0, v);
  for (auto it = nus.rbegin(); it != nus.rend(); ++it) chain.emplace_back(1, *it);
  for (double v : nus) chain.emplace_back(2, v);
  return chain;
}

WeightDataset build_dataset(const DatasetOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  WeightDataset d;
  d.hidden = o.hidden;
  const auto chain = dataset_chain(o.nu_count, o.nu_max);
  neural::NeuralMtlWeights prev;
  for (std::size_t k = 0; k < chain.size(); ++k) {
    const auto [law, nu] = chain[k];
    TrainOptions t;
    t.hidden = o.hidden;
    t.seed = o.seed * 100003ULL + k;
    const bool cold = k == 0;
    const bool new_law = !cold && chain[k - 1].first != law;
    // A neighbouring nu is a small step from the previous network: L-BFGS alone converges
    // from it (Adam's first steps, of size ~lr in every weight, would only undo the start). A
    // change of law is a bigger jump: Adam first, then a longer L-BFGS.
    t.steps = cold ? o.first_steps : (new_law ? o.switch_steps : o.steps);
    t.lbfgs_steps = cold ? o.first_lbfgs : (new_law ? o.switch_lbfgs : o.lbfgs_steps);
    t.learning_rate = cold ? 3e-3 : 1e-3;
    TrainReport r;
    const auto& name = neural::neural_laws()[static_cast<std::size_t>(law)];
    t.progress = o.progress && cold;
    t.label = "dataset " + name;
    prev = train_material(name, nu, t, cold ? nullptr : &prev, &r);
    d.law.push_back(law);
    d.nu.push_back(nu);
    d.weights.push_back(prev.flatten());
    d.fit_error.push_back(r.heldout.rms_log_error);
    d.correlation.push_back(r.heldout.correlation);
    d.stress_median.push_back(r.heldout.stress_median);
    d.stress_p99.push_back(r.heldout.stress_p99);
    if (o.progress) {
      const double el = seconds_since(t0);
      const double eta =
          el / static_cast<double>(k + 1) * static_cast<double>(chain.size() - k - 1);
      log::info(
          "dataset {:>3}/{} {:<11} nu = {:.4f}: corr {:.6f}, log-energy RMS {:.2e}, stress "
          "median {:.1e} p99 {:.1e} ({:.1f} s; ETA {})",
          k + 1, chain.size(), name, nu, r.heldout.correlation, r.heldout.rms_log_error,
          r.heldout.stress_median, r.heldout.stress_p99, r.seconds,
          ProgressLog::format_duration(eta));
    }
  }
  d.seconds = seconds_since(t0);
  return d;
}

void write_dataset(const std::string& path, const WeightDataset& d) {
  neural::ArrayFile f;
  f.format = kDatasetFormat;
  f.format_version = 1;
  f.text["hidden"] = join_hidden(d.hidden);
  f.numbers["count"] = static_cast<double>(d.size());
  f.numbers["seconds"] = d.seconds;
  const long n = static_cast<long>(d.size());
  const long p = d.weights.empty() ? 0 : static_cast<long>(d.weights[0].size());
  std::vector<double> law(d.law.begin(), d.law.end()), flat;
  for (const auto& w : d.weights) flat.insert(flat.end(), w.begin(), w.end());
  f.arrays["law"] = {{n}, law};
  f.arrays["nu"] = {{n}, d.nu};
  f.arrays["weights"] = {{n, p}, flat};
  f.arrays["fit_error"] = {{n}, d.fit_error};
  f.arrays["correlation"] = {{n}, d.correlation};
  f.arrays["stress_median"] = {{n}, d.stress_median};
  f.arrays["stress_p99"] = {{n}, d.stress_p99};
  neural::write_array_file(path, f);
}

WeightDataset read_dataset(const std::string& path) {
  const neural::ArrayFile f = neural::read_array_file(path, kDatasetFormat, 1);
  WeightDataset d;
  d.hidden = parse_hidden(f.text_attr("hidden", path), path + ": attribute 'hidden'");
  const double count = f.number_attr("count", path);
  if (!(count >= 1 && count <= 1e6 && count == std::floor(count)))
    throw InputError(path + ": attribute 'count' is not a dataset size");
  const long n = static_cast<long>(count);
  const long p =
      static_cast<long>(neural::NeuralMtlWeights::architecture(d.hidden).parameter_count());
  d.seconds = f.number_attr("seconds", path);
  for (double v : f.array("law", {n}, path).data) {
    if (!(v == 0 || v == 1 || v == 2))
      throw InputError(path + ": dataset 'law' holds " + std::to_string(v));
    d.law.push_back(static_cast<int>(v));
  }
  d.nu = f.array("nu", {n}, path).data;
  for (double v : d.nu)
    if (!(v >= 0 && v < 0.5)) throw InputError(path + ": dataset 'nu' holds " + std::to_string(v));
  const auto& W = f.array("weights", {n, p}, path).data;
  for (long i = 0; i < n; ++i) d.weights.emplace_back(W.begin() + i * p, W.begin() + (i + 1) * p);
  d.fit_error = f.array("fit_error", {n}, path).data;
  d.correlation = f.array("correlation", {n}, path).data;
  d.stress_median = f.array("stress_median", {n}, path).data;
  d.stress_p99 = f.array("stress_p99", {n}, path).data;
  return d;
}

// -------------------------------------------------------------------------------------------
// Generator model

struct Generator::Impl {
  std::vector<int> hidden;
  long P = 0, L = 0, H = 0, D = 0, T = 0;
  torch::Tensor w_mean, w_std, z_mean, z_std, betas;
  double clip = 0;
  Net enc, dec, eps;
  std::vector<int> cond_law;
  std::vector<double> cond_nu;

  std::vector<int> enc_sizes() const { return {int(P), int(H), int(L)}; }
  std::vector<int> dec_sizes() const { return {int(L), int(H), int(P)}; }
  std::vector<int> eps_sizes() const {
    return {int(L + kTimeDim + kCondDim), int(D), int(D), int(D), int(L)};
  }

  torch::Tensor encode(const torch::Tensor& w) const { return enc.forward((w - w_mean) / w_std); }
  torch::Tensor decode(const torch::Tensor& z) const { return dec.forward(z) * w_std + w_mean; }
  torch::Tensor predict_eps(const torch::Tensor& x, const torch::Tensor& t,
                            const torch::Tensor& c) const {
    return eps.forward(torch::cat({x, time_embedding(t), c}, 1));
  }

  // DDPM ancestral sampling with the x0-parameterised posterior, x0 clipped to the range of
  // the (normalised) training latents.
  torch::Tensor sample_latent(const torch::Tensor& c, std::uint64_t seed) const {
    torch::NoGradGuard ng;
    // eta = 1: ancestral DDPM. (DDIM's eta = 0 was measured worse here: its deterministic
    // path keeps the denoiser's x0 bias, the noise of the ancestral steps averages it out.)
    const double eta = 1.0;
    at::Generator gen = detail::generator(seed * 2654435761ULL + 12345);
    const long B = c.size(0);
    const std::vector<double> b = detail::to_vector(betas);
    std::vector<double> ab(b.size());
    double prod = 1;
    for (std::size_t t = 0; t < b.size(); ++t) ab[t] = (prod *= 1 - b[t]);
    torch::Tensor x = torch::randn({B, L}, gen, f64());
    for (long t = T - 1; t >= 0; --t) {
      const std::size_t ti = static_cast<std::size_t>(t);
      const torch::Tensor tt = torch::full({B}, static_cast<double>(t), f64());
      const torch::Tensor e = predict_eps(x, tt, c);
      torch::Tensor x0 = (x - std::sqrt(1 - ab[ti]) * e) / std::sqrt(ab[ti]);
      x0 = x0.clamp(-clip, clip);
      if (t == 0) {
        x = x0;
        break;
      }
      // x_{t-1} = sqrt(ab') x0 + sqrt(1 - ab' - s^2) eps + s z (Song et al. 2021): s of eta = 1
      // is the DDPM posterior's standard deviation, so that is ancestral DDPM sampling.
      const double abp = ab[ti - 1];
      const double s = eta * std::sqrt((1 - abp) / (1 - ab[ti]) * (1 - ab[ti] / abp));
      const torch::Tensor e0 = (x - std::sqrt(ab[ti]) * x0) / std::sqrt(1 - ab[ti]);
      x = std::sqrt(abp) * x0 + std::sqrt(std::max(0.0, 1 - abp - s * s)) * e0;
      if (s > 0) x = x + s * torch::randn({B, L}, gen, f64());
    }
    return x * z_std + z_mean;
  }
};

Generator::Generator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Generator::~Generator() = default;
Generator::Generator(Generator&&) noexcept = default;
Generator& Generator::operator=(Generator&&) noexcept = default;

const std::vector<int>& Generator::hidden() const {
  return impl_->hidden;
}

std::vector<std::pair<int, double>> Generator::trained_conditions() const {
  std::vector<std::pair<int, double>> c;
  for (std::size_t i = 0; i < impl_->cond_nu.size(); ++i)
    c.emplace_back(impl_->cond_law[i], impl_->cond_nu[i]);
  return c;
}

neural::NeuralMtlWeights Generator::sample(int law, double nu, std::uint64_t seed) const {
  if (law < 0 || law >= static_cast<int>(neural::neural_laws().size()) || !(nu >= 0 && nu < 0.5))
    throw std::invalid_argument("Generator::sample: law index or nu out of range");
  detail::apply_threads();
  torch::NoGradGuard ng;
  const torch::Tensor z = impl_->sample_latent(conditions({law}, {nu}), seed);
  neural::NeuralMtlWeights w = neural::NeuralMtlWeights::architecture(impl_->hidden);
  w.unflatten(detail::to_vector(impl_->decode(z)));
  w.law = neural::neural_laws()[static_cast<std::size_t>(law)];
  w.poisson_ratio = nu;
  w.source = "generator";
  return w;
}

std::vector<double> Generator::reconstruct(const std::vector<double>& flat) const {
  detail::apply_threads();
  torch::NoGradGuard ng;
  if (static_cast<long>(flat.size()) != impl_->P)
    throw std::invalid_argument("Generator::reconstruct: wrong parameter count");
  const torch::Tensor w = detail::from_vector(flat, 1, impl_->P);
  return detail::to_vector(impl_->decode(impl_->encode(w)));
}

void train_generator(const WeightDataset& data, const GeneratorOptions& o, const std::string& out,
                     GeneratorReport* report) {
  detail::apply_threads();
  if (data.size() < 2) throw InputError("train_generator: the dataset needs at least 2 networks");
  at::Generator gen = detail::generator(o.seed * 6364136223846793005ULL + 1442695040888963407ULL);
  Generator::Impl m;
  m.hidden = data.hidden;
  m.P = static_cast<long>(data.weights[0].size());
  m.L = o.latent;
  m.H = o.ae_hidden;
  m.D = o.ddpm_hidden;
  m.T = o.timesteps;
  m.cond_law = data.law;
  m.cond_nu = data.nu;
  const long N = static_cast<long>(data.size());
  std::vector<double> flat;
  for (const auto& w : data.weights) flat.insert(flat.end(), w.begin(), w.end());
  const torch::Tensor X = detail::from_vector(flat, N, m.P);
  m.w_mean = X.mean(0);
  // Per-coordinate spread, floored at 1e-3 of the typical one so near-constant weights are
  // not amplified into noise.
  torch::Tensor sd = X.std(0, false);
  m.w_std = torch::clamp_min(sd, 1e-3 * sd.mean().item<double>() + 1e-12);

  // 1. Autoencoder: normalised weights -> latent -> weights, full batch, MSE.
  auto t0 = std::chrono::steady_clock::now();
  m.enc = Net::random(m.enc_sizes(), gen);
  m.dec = Net::random(m.dec_sizes(), gen);
  const torch::Tensor Xn = (X - m.w_mean) / m.w_std;
  {
    std::vector<torch::Tensor> params = m.enc.parameters();
    for (auto& p : m.dec.parameters()) params.push_back(p);
    torch::optim::Adam opt(params, torch::optim::AdamOptions(1e-3));
    detail::TrainProgress bar("autoencoder", o.ae_steps, o.progress);
    for (int it = 0; it < o.ae_steps; ++it) {
      set_lr(opt, cosine_lr(1e-3, it, o.ae_steps));
      opt.zero_grad();
      torch::Tensor z = m.enc.forward(Xn);
      // Latent noise: the decoder must tolerate the DDPM's sampling error.
      if (o.ae_latent_noise > 0) z = z + o.ae_latent_noise * torch::randn(z.sizes(), gen, f64());
      torch::Tensor loss = (m.dec.forward(z) - Xn).pow(2).mean();
      loss.backward();
      opt.step();
      bar.update(it + 1, loss.item<double>());
    }
  }
  torch::Tensor Z;
  double ae_rms = 0;
  {
    torch::NoGradGuard ng;
    Z = m.enc.forward(Xn);
    ae_rms = std::sqrt((m.dec.forward(Z) - Xn).pow(2).mean().item<double>());
  }
  const double ae_seconds = seconds_since(t0);
  log::info("autoencoder: {} -> {} -> {}, RMS reconstruction error {:.2e} (normalised), {:.0f} s",
            m.P, m.H, m.L, ae_rms, ae_seconds);

  // 2. DDPM on normalised latents (epsilon prediction).
  t0 = std::chrono::steady_clock::now();
  m.z_mean = Z.mean(0);
  torch::Tensor zsd = Z.std(0, false);
  m.z_std = torch::clamp_min(zsd, 1e-3 * zsd.mean().item<double>() + 1e-12);
  const torch::Tensor Zn = (Z - m.z_mean) / m.z_std;
  m.clip = std::max(3.0, 1.5 * Zn.abs().max().item<double>());
  const std::vector<double> betas = cosine_betas(o.timesteps);
  m.betas = detail::from_vector(betas, 1, o.timesteps).reshape({o.timesteps});
  torch::Tensor ab = torch::cumprod(1 - m.betas, 0);
  const torch::Tensor C = conditions(data.law, data.nu);
  m.eps = Net::random(m.eps_sizes(), gen);
  double ddpm_loss = 0;
  {
    torch::optim::Adam opt(m.eps.parameters(), torch::optim::AdamOptions(1e-3));
    detail::TrainProgress bar("latent DDPM", o.ddpm_steps, o.progress);
    double acc = 0;
    int acc_n = 0;
    for (int it = 0; it < o.ddpm_steps; ++it) {
      set_lr(opt, cosine_lr(1e-3, it, o.ddpm_steps));
      const torch::Tensor idx = torch::randint(N, {o.ddpm_batch}, gen, torch::kLong);
      const torch::Tensor t = torch::randint(o.timesteps, {o.ddpm_batch}, gen, torch::kLong);
      const torch::Tensor noise = torch::randn({o.ddpm_batch, m.L}, gen, f64());
      const torch::Tensor a = ab.index_select(0, t).unsqueeze(1);
      const torch::Tensor xt =
          torch::sqrt(a) * Zn.index_select(0, idx) + torch::sqrt(1 - a) * noise;
      opt.zero_grad();
      torch::Tensor loss =
          (m.predict_eps(xt, t.to(torch::kFloat64), C.index_select(0, idx)) - noise).pow(2).mean();
      loss.backward();
      opt.step();
      const double l = loss.item<double>();
      if (it >= o.ddpm_steps - 500) {
        acc += l;
        ++acc_n;
      }
      bar.update(it + 1, l);
    }
    ddpm_loss = acc / std::max(1, acc_n);
  }
  const double ddpm_seconds = seconds_since(t0);
  log::info("latent DDPM: T = {}, MLP {} -> {} -> {} -> {} -> {}, final loss {:.3e}, {:.0f} s",
            o.timesteps, m.L + kTimeDim + kCondDim, m.D, m.D, m.D, m.L, ddpm_loss, ddpm_seconds);

  // 3. One file: every layer, the normalisation statistics and the schedule.
  neural::ArrayFile f;
  f.format = kGeneratorFormat;
  f.format_version = kGeneratorVersion;
  f.text["hidden"] = join_hidden(m.hidden);
  f.text["laws"] = "corotated,neo_hookean,stvk";
  f.text["schedule"] = "cosine";
  f.text["prediction"] = "epsilon";
  f.text["condition"] = "law one-hot, nu/0.25 - 1, sin/cos(k pi nu / 0.5) k = 1..3";
  f.numbers["params"] = static_cast<double>(m.P);
  f.numbers["latent"] = static_cast<double>(m.L);
  f.numbers["ae_hidden"] = static_cast<double>(m.H);
  f.numbers["ddpm_hidden"] = static_cast<double>(m.D);
  f.numbers["timesteps"] = static_cast<double>(m.T);
  f.numbers["time_dim"] = kTimeDim;
  f.numbers["cond_dim"] = kCondDim;
  f.numbers["dataset_size"] = static_cast<double>(N);
  f.numbers["clip"] = m.clip;
  f.numbers["ae_rms"] = ae_rms;
  f.numbers["ddpm_loss"] = ddpm_loss;
  f.numbers["seed"] = static_cast<double>(o.seed);
  f.numbers["dataset_seconds"] = data.seconds;
  f.numbers["ae_seconds"] = ae_seconds;
  f.numbers["ddpm_seconds"] = ddpm_seconds;
  f.arrays["w_mean"] = {{m.P}, detail::to_vector(m.w_mean)};
  f.arrays["w_std"] = {{m.P}, detail::to_vector(m.w_std)};
  f.arrays["z_mean"] = {{m.L}, detail::to_vector(m.z_mean)};
  f.arrays["z_std"] = {{m.L}, detail::to_vector(m.z_std)};
  f.arrays["betas"] = {{m.T}, betas};
  f.arrays["dataset_law"] = {{N}, std::vector<double>(data.law.begin(), data.law.end())};
  f.arrays["dataset_nu"] = {{N}, data.nu};
  m.enc.store(f, "enc");
  m.dec.store(f, "dec");
  m.eps.store(f, "eps");
  neural::write_array_file(out, f);
  if (report) {
    report->ae_seconds = ae_seconds;
    report->ddpm_seconds = ddpm_seconds;
    report->ae_rms = ae_rms;
    report->ddpm_loss = ddpm_loss;
    report->values = m.enc.values() + m.dec.values() + m.eps.values() + 2 * m.P + 2 * m.L + m.T;
  }
}

GeneratorCheck check_generator(const Generator& g, const WeightDataset& data, std::uint64_t seed) {
  std::vector<double> ae, smp;
  for (std::size_t i = 0; i < data.size(); ++i) {
    neural::NeuralMtlWeights w = neural::NeuralMtlWeights::architecture(data.hidden);
    w.law = neural::neural_laws()[static_cast<std::size_t>(data.law[i])];
    w.poisson_ratio = data.nu[i];
    w.unflatten(g.reconstruct(data.weights[i]));
    ae.push_back(evaluate_fit(w, heldout_deformations()).correlation);
    smp.push_back(
        evaluate_fit(g.sample(data.law[i], data.nu[i], seed), heldout_deformations()).correlation);
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  GeneratorCheck c;
  c.ae_min = *std::min_element(ae.begin(), ae.end());
  c.ae_median = median(ae);
  c.sample_min = *std::min_element(smp.begin(), smp.end());
  c.sample_median = median(smp);
  return c;
}

Generator Generator::load(const std::string& path) {
  detail::apply_threads();
  const neural::ArrayFile f = neural::read_array_file(path, kGeneratorFormat, kGeneratorVersion);
  auto m = std::make_unique<Impl>();
  auto count = [&](const char* name, double lo, double hi) {
    const double v = f.number_attr(name, path);
    if (!(v >= lo && v <= hi && v == std::floor(v)))
      throw InputError(path + ": attribute '" + name + "' = " + std::to_string(v) +
                       " is not an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                       "]");
    return static_cast<long>(v);
  };
  m->hidden = parse_hidden(f.text_attr("hidden", path), path + ": attribute 'hidden'");
  if (f.text_attr("laws", path) != "corotated,neo_hookean,stvk")
    throw InputError(path + ": attribute 'laws' does not list corotated,neo_hookean,stvk");
  if (f.text_attr("schedule", path) != "cosine")
    throw InputError(path + ": schedule '" + f.text_attr("schedule", path) + "' is not cosine");
  m->P = count("params", 1, 1e6);
  const long expected =
      static_cast<long>(neural::NeuralMtlWeights::architecture(m->hidden).parameter_count());
  if (m->P != expected)
    throw InputError(path + ": attribute 'params' = " + std::to_string(m->P) + " but hidden " +
                     f.text_attr("hidden", path) + " has " + std::to_string(expected));
  m->L = count("latent", 1, 4096);
  m->H = count("ae_hidden", 1, 65536);
  m->D = count("ddpm_hidden", 1, 65536);
  m->T = count("timesteps", 1, 100000);
  if (count("time_dim", 1, 4096) != kTimeDim || count("cond_dim", 1, 4096) != kCondDim)
    throw InputError(path + ": time_dim / cond_dim do not match this gen4d (" +
                     std::to_string(kTimeDim) + ", " + std::to_string(kCondDim) + ")");
  const long N = count("dataset_size", 1, 1e6);
  m->clip = f.number_attr("clip", path);
  if (!(m->clip > 0)) throw InputError(path + ": attribute 'clip' must be > 0");
  auto vec = [&](const char* name, long n) {
    return detail::from_vector(f.array(name, {n}, path).data, 1, n).reshape({n});
  };
  m->w_mean = vec("w_mean", m->P);
  m->w_std = vec("w_std", m->P);
  m->z_mean = vec("z_mean", m->L);
  m->z_std = vec("z_std", m->L);
  m->betas = vec("betas", m->T);
  for (double b : detail::to_vector(m->betas))
    if (!(b > 0 && b < 1)) throw InputError(path + ": dataset 'betas' holds " + std::to_string(b));
  for (double v : f.array("dataset_law", {N}, path).data) {
    if (!(v == 0 || v == 1 || v == 2))
      throw InputError(path + ": dataset 'dataset_law' holds " + std::to_string(v));
    m->cond_law.push_back(static_cast<int>(v));
  }
  m->cond_nu = f.array("dataset_nu", {N}, path).data;
  m->enc = Net::load(f, "enc", m->enc_sizes(), path);
  m->dec = Net::load(f, "dec", m->dec_sizes(), path);
  m->eps = Net::load(f, "eps", m->eps_sizes(), path);
  // No layers beyond the expected ones (a file from a deeper model would otherwise load).
  for (const char* p : {"enc2_W", "dec2_W", "eps4_W"})
    if (f.arrays.count(p))
      throw InputError(path + ": unexpected dataset '" + std::string(p) +
                       "' (a different generator architecture)");
  return Generator(std::move(m));
}

}  // namespace gen4d::neural_train
