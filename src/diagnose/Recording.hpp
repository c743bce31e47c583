//! Recordings for `gen4d diagnose`: marker trajectories (observed positions) and accelerometer
//! signals attached to reference points of the body, read from CSV or HDF5 and validated.
//!
//! CSV: a header naming the columns (any order), then one sample per row:
//!   positions       marker,X,Y,Z,t,x,y,z
//!   accelerometers  sensor,X,Y,Z,t,ax,ay,az
//! Lines starting with '#' and blank lines are skipped; CRLF line endings are accepted.
//! HDF5: 1-D datasets named like the CSV columns, at the root (one kind) or in the groups
//! /positions and /accelerations (both kinds); ids are integer or string datasets.
//! Values not measured: an empty CSV cell, a value column left out (e.g. sensor,X,Y,Z,t,az),
//! NaN or a missing value dataset in HDF5, or a column named in ReadOptions::unmeasured. A
//! sample with no measured value is skipped; a channel with none is an error.
//! Every error is an InputError naming the file and the line (CSV, 1-based) or the dataset and
//! row (HDF5, 0-based).
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace gen4d::diagnose {

enum class ChannelKind { Position, Acceleration };

//! One marker (observed positions, m) or accelerometer (m/s^2) attached at reference point X.
struct Channel {
  std::string id;  // marker / sensor id as written in the file
  ChannelKind kind = ChannelKind::Position;
  std::array<double, 3> X{};                 // reference position, m
  std::vector<double> t;                     // s, strictly increasing
  std::vector<std::array<double, 3>> value;  // x,y,z (position) or ax,ay,az; 0 if not measured
  //! Per sample, which of the three values were measured; empty: all of them.
  std::vector<std::array<bool, 3>> measured;
  std::vector<long> line;  // source line (CSV) or row index (HDF5) of each sample, for messages
  //! The file this channel was read from, for messages (empty: the recording's source).
  std::string file;
  //! Whether component d (0, 1, 2) of sample k was measured.
  bool has(std::size_t k, int d) const {
    return measured.empty() || measured[k][static_cast<std::size_t>(d)];
  }
};

struct Recording {
  std::string source;             // file path(s) as given
  std::vector<Channel> channels;  // in order of first appearance; positions and accelerations
  std::size_t samples() const;    // total samples over channels
  double t_begin() const;         // earliest sample time (0 without channels)
  double t_end() const;           // latest sample time (0 without channels)
};

//! "marker" or "sensor": the word used for a channel of `kind` in files and messages.
const char* id_column(ChannelKind kind);

struct ReadOptions {
  //! Value columns (x, y, z, ax, ay, az) not measured in any sample, whatever the file holds
  //! there (files that write 0 for an axis the sensor lacks); names of the other kind are
  //! ignored.
  std::vector<std::string> unmeasured;
};

//! The value columns of both kinds: x, y, z, ax, ay, az.
const std::vector<std::string>& value_column_names();

//! Reads a CSV (.csv) or HDF5 (.h5/.hdf5) recording; throws InputError naming file and
//! line/dataset (or, for a name in opt.unmeasured that is no value column, the option).
//! Other extensions are read as HDF5 when the file carries the HDF5 signature, else as CSV.
Recording read_recording(const std::string& path, const ReadOptions& opt = {});

//! Appends the channels of `more` (e.g. accelerometers in a second file); duplicate ids of the
//! same kind are an error (InputError naming both files and the id).
void merge_recordings(Recording& into, Recording&& more);

//! Throws InputError naming file, line and marker for the first channel whose X is not inside
//! the body.
void check_attached(const Recording& rec,
                    const std::function<bool(const std::array<double, 3>&)>& inside);

//! The positions file and the accelerometer file written by write_recording_csv for `path`:
//! "a/rec.csv" gives "a/rec.csv" and "a/rec-acc.csv".
std::string acceleration_csv_path(const std::string& path);

//! Writes a recording as CSV (one file per kind present: path for positions, and, if any
//! accelerometers, path with suffix "-acc" before the extension) atomically (temporary name +
//! rename). Numbers are written with round-trip precision; a value not measured is an empty
//! cell, a sample with none measured is left out. Used by tests and the generator of
//! synthetic data. Throws RuntimeError on an I/O failure or an id that CSV cannot hold.
void write_recording_csv(const Recording& rec, const std::string& path);

}  // namespace gen4d::diagnose
