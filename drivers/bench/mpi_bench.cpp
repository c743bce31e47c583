// bench_mpi — the MPI transport this job runs on, printed as JSON: the numbers the scaling
// model (jobs/scaling/model.py) needs for its communication terms.
//
// Sample runs:
//   mpirun -np 2 build-scaling/drivers/bench_mpi
//   mpirun -np 2 build-scaling/drivers/bench_mpi --max-bytes 1048576 --repeats 5
//
// Description:
//   1. Ping-pong between ranks 0 and 1 (the other ranks wait in a barrier) for message sizes
//      from --min-bytes to --max-bytes, doubling: one-way time = round trip / 2, bandwidth =
//      bytes / one-way time. Each size runs a number of round trips that scales inversely with
//      the size (at least 10, at most --max-round-trips, 10,000 by default), best of --repeats.
//   2. MPI_Allreduce of one double (MPI_SUM) over all ranks: the latency of a scalar
//      collective, mean time per call, best of --repeats.
//   3. MPI_Allgather of 68 int64 per rank: the wire format of one of gen4d's exact global sums
//      (parallel/Reduce.cpp, ExactSum::kWords), so the model charges the reduction the code
//      really does.
// Every rank must call it with the same options; needs at least 2 ranks.
#include <mpi.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace {

constexpr int kExactSumWords = 68;  // parallel/Reduce.hpp: ExactSum::kWords

struct Options {
  long min_bytes = 8;
  long max_bytes = 16L << 20;
  int repeats = 3;
  long collective_calls = 2000;
  long max_round_trips = 10000;
  std::string json;
};

//! Round trips for a message of `bytes`: about 64 MiB moved each way, 10 .. `most`.
long round_trips(long bytes, long most) {
  return std::clamp(64L * 1024 * 1024 / bytes, std::min(10L, most), most);
}

//! Seconds of one one-way message of `bytes` between ranks 0 and 1 (best of `repeats`),
//! valid on rank 0; other ranks only take part in the barriers.
double ping_pong(long bytes, long n, int repeats, std::vector<char>& buf) {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  const int count = static_cast<int>(bytes);
  double best = 1e300;
  for (int r = 0; r < repeats + 1; ++r) {  // the first pass warms up the path
    MPI_Barrier(MPI_COMM_WORLD);
    const double t0 = MPI_Wtime();
    if (rank == 0) {
      for (long i = 0; i < n; ++i) {
        MPI_Send(buf.data(), count, MPI_CHAR, 1, 0, MPI_COMM_WORLD);
        MPI_Recv(buf.data(), count, MPI_CHAR, 1, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      }
    } else if (rank == 1) {
      for (long i = 0; i < n; ++i) {
        MPI_Recv(buf.data(), count, MPI_CHAR, 0, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        MPI_Send(buf.data(), count, MPI_CHAR, 0, 0, MPI_COMM_WORLD);
      }
    }
    const double t = (MPI_Wtime() - t0) / (2.0 * static_cast<double>(n));
    if (r > 0) best = std::min(best, t);
  }
  return best;
}

//! Mean seconds per call of `f` over `calls` calls, max over ranks, best of `repeats`.
template <class F>
double per_call(long calls, int repeats, const F& f) {
  double best = 1e300;
  for (int r = 0; r < repeats + 1; ++r) {
    MPI_Barrier(MPI_COMM_WORLD);
    const double t0 = MPI_Wtime();
    for (long i = 0; i < calls; ++i) f();
    double t = (MPI_Wtime() - t0) / static_cast<double>(calls), tmax = 0;
    MPI_Allreduce(&t, &tmax, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    if (r > 0) best = std::min(best, tmax);
  }
  return best;
}

int run(const Options& o) {
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (size < 2) {
    if (rank == 0)
      std::fprintf(stderr, "bench_mpi: needs at least 2 ranks (run it under mpirun -np 2)\n");
    return 2;
  }
  // Where the ranks run: one host means the shared-memory transport.
  char host[MPI_MAX_PROCESSOR_NAME] = {};
  int len = 0;
  MPI_Get_processor_name(host, &len);
  std::vector<char> hosts(static_cast<std::size_t>(size) * MPI_MAX_PROCESSOR_NAME);
  MPI_Gather(host, MPI_MAX_PROCESSOR_NAME, MPI_CHAR, hosts.data(), MPI_MAX_PROCESSOR_NAME, MPI_CHAR,
             0, MPI_COMM_WORLD);
  std::vector<std::string> names;
  for (int r = 0; r < size; ++r)
    names.emplace_back(&hosts[static_cast<std::size_t>(r) * MPI_MAX_PROCESSOR_NAME]);
  std::sort(names.begin(), names.end());
  const long distinct = std::unique(names.begin(), names.end()) - names.begin();

  std::vector<char> buf(static_cast<std::size_t>(o.max_bytes), 1);
  std::string rows;
  for (long b = o.min_bytes; b <= o.max_bytes; b *= 2) {
    const long n = round_trips(b, o.max_round_trips);
    const double t = ping_pong(b, n, o.repeats, buf);
    char line[256];
    std::snprintf(line, sizeof line,
                  "%s    {\"bytes\": %ld, \"round_trips\": %ld, \"one_way_us\": %.4f, "
                  "\"MBps\": %.2f}",
                  rows.empty() ? "" : ",\n", b, n, 1e6 * t, b / t / 1e6);
    rows += line;
  }
  double x = 1.0, y = 0.0;
  const double allreduce = per_call(o.collective_calls, o.repeats, [&] {
    MPI_Allreduce(&x, &y, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  });
  std::vector<std::int64_t> words(kExactSumWords, 1),
      gathered(static_cast<std::size_t>(kExactSumWords) * size);
  const double allgather = per_call(o.collective_calls, o.repeats, [&] {
    MPI_Allgather(words.data(), kExactSumWords, MPI_INT64_T, gathered.data(), kExactSumWords,
                  MPI_INT64_T, MPI_COMM_WORLD);
  });
  if (rank != 0) return 0;
  char head[512];
  std::snprintf(head, sizeof head,
                "{\n  \"benchmark\": \"mpi\",\n  \"ranks\": %d,\n  \"hosts\": %ld,\n"
                "  \"transport\": \"%s\",\n  \"repeats\": %d,\n  \"pingpong\": [\n",
                size, distinct, distinct == 1 ? "shared memory (one host)" : "network", o.repeats);
  char tail[512];
  std::snprintf(tail, sizeof tail,
                "\n  ],\n  \"allreduce_1_double_us\": %.4f,\n"
                "  \"allgather_exact_sum\": {\"bytes_per_rank\": %d, \"us\": %.4f},\n"
                "  \"collective_calls\": %ld\n}\n",
                1e6 * allreduce, 8 * kExactSumWords, 1e6 * allgather, o.collective_calls);
  const std::string json = head + rows + tail;
  std::fputs(json.c_str(), stdout);
  if (!o.json.empty()) {
    const std::string tmp = o.json + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    const bool ok = f && std::fputs(json.c_str(), f) >= 0 && std::fclose(f) == 0 &&
                    std::rename(tmp.c_str(), o.json.c_str()) == 0;
    if (!ok) {
      std::fprintf(stderr, "bench_mpi: %s: cannot write the JSON\n", o.json.c_str());
      return 1;
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  Options o;
  CLI::App app{"MPI ping-pong latency/bandwidth and scalar collective latency, as JSON"};
  app.add_option("--min-bytes", o.min_bytes, "Smallest ping-pong message")
      ->check(CLI::Range(1L, 1L << 30));
  app.add_option("--max-bytes", o.max_bytes, "Largest ping-pong message")
      ->check(CLI::Range(1L, 1L << 30));
  app.add_option("--repeats", o.repeats, "Timed passes per measurement (best is kept)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--collective-calls", o.collective_calls, "Calls per collective timing pass")
      ->check(CLI::Range(1L, 10000000L));
  app.add_option("--max-round-trips", o.max_round_trips, "Most ping-pong round trips per size")
      ->check(CLI::Range(1L, 100000000L));
  app.add_option("--json", o.json, "Also write the JSON to this file");
  int code = 0;
  try {
    app.parse(argc, argv);
    if (o.min_bytes > o.max_bytes)
      throw CLI::ValidationError("--min-bytes", "must not exceed --max-bytes");
    code = run(o);
  } catch (const CLI::ParseError& e) {
    code = rank == 0 ? app.exit(e) : (e.get_exit_code() != 0 ? 2 : 0);
  }
  MPI_Finalize();
  return code;
}
