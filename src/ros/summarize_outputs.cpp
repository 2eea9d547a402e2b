// summarize_outputs: compares what the visual_gyro node published (a bag recorded with
// `rosbag record <ns>/rotation <ns>/imu`) with the ground truth in the sequence bag it was fed,
// prints a summary and, as its last line, evaluate's JSON line plus imu_published and
// latency_ms.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>

#include "bag_tools.h"
#include "command_line.h"

namespace {

const char* const kUsage =
    "usage: summarize_outputs <sequence.bag> <outputs.bag> [--ns /visual_gyro] [--dataset NAME]\n";

int run(int argc, char** argv) {
  std::vector<std::string> positional;
  std::string ns = "/visual_gyro", dataset;
  for (visual_gyro::cli::Arguments args(argc, argv); args.next();) {
    if (args.is("-h") || args.is("--help")) {
      std::printf("%s", kUsage);
      return 0;
    } else if (args.is("--ns")) {
      ns = args.value();
    } else if (args.is("--dataset")) {
      dataset = args.value();
    } else {
      args.positional(&positional, 2);
    }
  }
  if (positional.size() != 2) throw visual_gyro::cli::UsageError("a sequence bag and an outputs bag are needed");
  const std::string sequence_bag = positional[0], outputs_bag = positional[1];
  if (dataset.empty()) {
    dataset = sequence_bag.substr(sequence_bag.find_last_of('/') + 1);
    if (dataset.size() > 4 && dataset.substr(dataset.size() - 4) == ".bag") dataset.resize(dataset.size() - 4);
  }
  {
    const auto truth = visual_gyro::bag_tools::readSequenceBag(sequence_bag);
    std::vector<visual_gyro::RotationEstimate> estimates;
    int imus = 0;
    rosbag::Bag bag;
    bag.open(outputs_bag, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery({ns + "/rotation", ns + "/imu"}));
    for (const rosbag::MessageInstance& m : view) {
      if (m.getTopic() == ns + "/rotation") {
        if (auto p = m.instantiate<visual_gyro::RotationEstimate>()) estimates.push_back(*p);
      } else if (m.instantiate<sensor_msgs::Imu>()) {
        ++imus;
      }
    }
    bag.close();
    // Recorders write in arrival order; evaluate in stamp order.
    std::sort(estimates.begin(), estimates.end(),
              [](const auto& a, const auto& b) { return a.previous_stamp < b.previous_stamp; });
    const auto summary = visual_gyro::bag_tools::evaluateOutputs(estimates, imus, truth, dataset);
    std::printf("%s\n%s\n", summary.text().c_str(), summary.json().c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return visual_gyro::cli::runCommand("summarize_outputs", kUsage, [&] { return run(argc, argv); });
}
