// Pinocchio's side of the peer benchmark, timed in compiled C++ (no Python in the loop).
//
// Built and run by benches/peer/peer.py (see its docstring), which writes the input file:
//   urdf <path>
//   joints <name> <name> ...      the joints of the MCPC chains (every other joint is locked at 0)
//   tools <frame> <frame> ...     the tool links, in treecal's order
//   rounds <n>
//   config <q_1> ... <q_n> <x y z of each tool>   one line per configuration (SI units)
// and reads its output: one line `<operation> <median ns> <minimum ns>` per operation, then
// `max_position_error <m>` (tool positions against treecal's) and `model <njoints> <nq>`.
//
// The calls are the ones a C++ user of Pinocchio makes: forwardKinematics +
// updateFramePlacement of each tool (fk), then computeFrameKinematicRegressor of each tool into
// a preallocated 6 x 6·njoints matrix (jacobian). Timing as peer.py's: rounds of about 2 ms,
// the mean ns per call in each round, median and minimum over the rounds.

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/algorithm/regressor.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace pin = pinocchio;

struct Input {
  std::string urdf;
  std::vector<std::string> joints, tools;
  int rounds = 101;
  std::vector<std::vector<double>> values, positions;
};

static Input read_input(const char *path) {
  Input input;
  std::ifstream file(path);
  if (!file) {
    std::cerr << "cannot read " << path << "\n";
    std::exit(2);
  }
  std::string line;
  while (std::getline(file, line)) {
    std::istringstream words(line);
    std::string key, word;
    words >> key;
    if (key == "urdf") {
      std::getline(words >> std::ws, input.urdf);
    } else if (key == "joints") {
      while (words >> word) input.joints.push_back(word);
    } else if (key == "tools") {
      while (words >> word) input.tools.push_back(word);
    } else if (key == "rounds") {
      words >> input.rounds;
    } else if (key == "config") {
      std::vector<double> q(input.joints.size()), p(3 * input.tools.size());
      for (double &v : q) words >> v;
      for (double &v : p) words >> v;
      input.values.push_back(q);
      input.positions.push_back(p);
    }
  }
  return input;
}

static pin::Model reduced_model(const Input &input) {
  pin::Model full;
  pin::urdf::buildModel(input.urdf, full);
  std::vector<pin::JointIndex> locked;
  for (pin::JointIndex j = 1; j < (pin::JointIndex)full.njoints; ++j) {
    if (std::find(input.joints.begin(), input.joints.end(), full.names[j]) == input.joints.end())
      locked.push_back(j);
  }
  return pin::buildReducedModel(full, locked, pin::neutral(full));
}

static Eigen::VectorXd configuration(const pin::Model &model, const Input &input,
                                     const std::vector<double> &values) {
  Eigen::VectorXd q = pin::neutral(model);
  for (size_t k = 0; k < input.joints.size(); ++k) {
    const auto &joint = model.joints[model.getJointId(input.joints[k])];
    if (joint.nq() == 2) {  // continuous: (cos, sin)
      q[joint.idx_q()] = std::cos(values[k]);
      q[joint.idx_q() + 1] = std::sin(values[k]);
    } else {
      q[joint.idx_q()] = values[k];
    }
  }
  return q;
}

// Median and minimum over `rounds` rounds of about 2 ms of the mean ns per call.
template <typename Call>
static std::pair<double, double> timing_ns(int rounds, const std::vector<Eigen::VectorXd> &qs,
                                           Call call) {
  using Clock = std::chrono::steady_clock;
  auto seconds = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
  };
  auto start = Clock::now();
  for (const auto &q : qs) call(q);
  double once = seconds(start, Clock::now()) / qs.size();
  long repeats = std::max(1L, (long)(0.002 / std::max(once, 1e-9)) / (long)qs.size());
  std::vector<double> samples;
  for (int r = 0; r < rounds; ++r) {
    start = Clock::now();
    for (long k = 0; k < repeats; ++k)
      for (const auto &q : qs) call(q);
    samples.push_back(seconds(start, Clock::now()) * 1e9 / (repeats * qs.size()));
  }
  std::sort(samples.begin(), samples.end());
  return {samples[samples.size() / 2], samples.front()};
}

int main(int argc, char **argv) {
  if (argc != 2) {
    std::cerr << "usage: pinocchio_peer INPUT (written by benches/peer/peer.py)\n";
    return 2;
  }
  const Input input = read_input(argv[1]);
  const pin::Model model = reduced_model(input);
  pin::Data data(model);
  std::vector<pin::FrameIndex> tools;
  for (const auto &name : input.tools) tools.push_back(model.getFrameId(name));
  std::vector<Eigen::VectorXd> qs;
  for (const auto &values : input.values) qs.push_back(configuration(model, input, values));

  double error = 0.0;
  for (size_t c = 0; c < qs.size(); ++c) {
    pin::forwardKinematics(model, data, qs[c]);
    for (size_t t = 0; t < tools.size(); ++t) {
      const auto &p = pin::updateFramePlacement(model, data, tools[t]).translation();
      for (int i = 0; i < 3; ++i)
        error = std::max(error, std::abs(p[i] - input.positions[c][3 * t + i]));
    }
  }

  pin::Data::Matrix6x regressor(6, 6 * (model.njoints - 1));
  double sink = 0.0;  // keeps the optimiser from dropping the calls
  auto fk = [&](size_t n) {
    return [&, n](const Eigen::VectorXd &q) {
      pin::forwardKinematics(model, data, q);
      for (size_t t = 0; t < n; ++t) sink += pin::updateFramePlacement(model, data, tools[t]).translation()[0];
    };
  };
  auto jacobian = [&](size_t n) {
    return [&, n](const Eigen::VectorXd &q) {
      pin::forwardKinematics(model, data, q);
      for (size_t t = 0; t < n; ++t) {
        pin::updateFramePlacement(model, data, tools[t]);
        pin::computeFrameKinematicRegressor(model, data, tools[t], pin::WORLD, regressor);
        sink += regressor(0, 0);
      }
    };
  };
  const std::pair<const char *, std::pair<double, double>> rows[] = {
      {"fk_both_tools", timing_ns(input.rounds, qs, fk(tools.size()))},
      {"fk_one_tool", timing_ns(input.rounds, qs, fk(1))},
      {"jacobian_both_tools", timing_ns(input.rounds, qs, jacobian(tools.size()))},
      {"jacobian_one_tool", timing_ns(input.rounds, qs, jacobian(1))},
  };
  for (const auto &row : rows) std::printf("%s %.3f %.3f\n", row.first, row.second.first, row.second.second);
  std::printf("max_position_error %.3e\n", error);
  std::printf("model %d %d\n", (int)model.njoints - 1, (int)model.nq);
  std::fprintf(stderr, "checksum %g\n", sink);
  return 0;
}
