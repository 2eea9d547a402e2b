// summarize_outputs: compares what the visual_gyro node published (a bag recorded with
// `rosbag record <ns>/rotation <ns>/imu`) with the ground truth in the sequence bag it was fed,
// prints a summary and, as its last line, evaluate's JSON line plus imu_published and
// latency_ms.
#include <algorithm>
#include <cstdio>
#include <string>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>

#include "bag_tools.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: summarize_outputs <sequence.bag> <outputs.bag> [--ns /visual_gyro] [--dataset NAME]\n");
    return 2;
  }
  const std::string sequence_bag = argv[1], outputs_bag = argv[2];
  std::string ns = "/visual_gyro", dataset;
  for (int i = 3; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--ns") ns = argv[i + 1];
    else if (a == "--dataset") dataset = argv[i + 1];
    else {
      std::fprintf(stderr, "summarize_outputs: unknown option '%s'\n", a.c_str());
      return 2;
    }
  }
  if (dataset.empty()) {
    dataset = sequence_bag.substr(sequence_bag.find_last_of('/') + 1);
    if (dataset.size() > 4 && dataset.substr(dataset.size() - 4) == ".bag") dataset.resize(dataset.size() - 4);
  }
  try {
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
  } catch (const std::exception& e) {
    std::fprintf(stderr, "summarize_outputs: %s\n", e.what());
    return 1;
  }
  return 0;
}
