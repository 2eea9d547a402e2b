// integrate_imu: integrates the ~imu messages recorded from the visual_gyro node the way a fusion
// filter does (each rate held from its stamp to the next message's) and prints the orientation
// error against the sequence bag's ground truth over time (scripts/stamp_study.sh).
#include <cstdio>
#include <stdexcept>
#include <algorithm>
#include <string>
#include <vector>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>

#include "bag_tools.h"
#include "command_line.h"
#include "imu_integration.h"
#include "json_writer.h"
#include "ros_conversions.h"

namespace {

const char* const kUsage =
    "usage: integrate_imu <sequence.bag> <outputs.bag> [options]\n"
    "  --ns NS        the node's namespace: reads NS/imu (default /visual_gyro)\n"
    "  --step S       error sampled every S seconds (default 0.01)\n"
    "  --print-every S  one line of the error series every S seconds (default 0.5; 0: none)\n"
    "Prints the series and, last, one JSON line: imu, rms_deg, mean_deg, max_deg, final_deg.\n";

int run(int argc, char** argv) {
  std::vector<std::string> positional;
  std::string ns = "/visual_gyro";
  double step = 0.01, print_every = 0.5;
  for (visual_gyro::cli::Arguments args(argc, argv); args.next();) {
    if (args.is("-h") || args.is("--help")) {
      std::printf("%s", kUsage);
      return 0;
    } else if (args.is("--ns")) {
      ns = args.value();
    } else if (args.is("--step")) {
      step = args.doubleValue(1e-6, 1e6);
    } else if (args.is("--print-every")) {
      print_every = args.doubleValue(0.0, 1e9);
    } else {
      args.positional(&positional, 2);
    }
  }
  if (positional.size() != 2) throw visual_gyro::cli::UsageError("a sequence bag and an outputs bag are needed");
  const std::string sequence_bag = positional[0], outputs_bag = positional[1];
  namespace ii = visual_gyro::imu_integration;
  {
    const auto contents = visual_gyro::bag_tools::readSequenceBag(sequence_bag);
    if (contents.poses.size() < 2) {
      throw std::runtime_error(sequence_bag + " has no ground-truth poses to compare with");
    }
    std::vector<ii::TruthSample> truth;
    for (const auto& p : contents.poses) {
      truth.push_back({p->header.stamp.toSec(),
                       visual_gyro::ros_conversions::fromMsg(p->pose.orientation).toRotationMatrix()});
    }
    rosbag::Bag bag;
    bag.open(outputs_bag, rosbag::bagmode::Read);
    std::vector<ii::RateSample> rates;
    rosbag::View view(bag, rosbag::TopicQuery({ns + "/imu"}));
    for (const rosbag::MessageInstance& m : view) {
      if (auto imu = m.instantiate<sensor_msgs::Imu>()) {
        rates.push_back({imu->header.stamp.toSec(), Eigen::Vector3d(imu->angular_velocity.x, imu->angular_velocity.y,
                                                                    imu->angular_velocity.z)});
      }
    }
    bag.close();
    if (rates.empty()) {
      throw std::runtime_error(outputs_bag + " has no messages on " + ns + "/imu");
    }
    std::sort(rates.begin(), rates.end(), [](const ii::RateSample& a, const ii::RateSample& b) {
      return a.stamp < b.stamp;
    });
    const ii::IntegrationError error = ii::integrationError(rates, truth, step);
    if (print_every > 0.0) {
      std::printf("time_s error_deg\n");
      double next = 0.0;
      for (const ii::ErrorPoint& p : error.series) {
        if (p.time + 1e-9 < next) continue;
        std::printf("%.2f %.3f\n", p.time, p.error_deg);
        next += print_every;
      }
    }
    visual_gyro::JsonObject line;
    line.add("imu", static_cast<long long>(rates.size()))
        .add("rms_deg", error.rms_deg)
        .add("mean_deg", error.mean_deg)
        .add("max_deg", error.max_deg)
        .add("final_deg", error.final_deg);
    std::printf("%s\n", line.str().c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return visual_gyro::cli::runCommand("integrate_imu", kUsage, [&] { return run(argc, argv); });
}
