// integrate_imu: integrates the ~imu messages recorded from the visual_gyro node the way a fusion
// filter does (each rate held from its stamp to the next message's) and prints the orientation
// error against the sequence bag's ground truth over time (scripts/stamp_study.sh).
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <algorithm>
#include <string>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>

#include "bag_tools.h"
#include "imu_integration.h"
#include "ros_conversions.h"

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: integrate_imu <sequence.bag> <outputs.bag> [options]\n"
               "  --ns NS        the node's namespace: reads NS/imu (default /visual_gyro)\n"
               "  --step S       error sampled every S seconds (default 0.01)\n"
               "  --print-every S  one line of the error series every S seconds (default 0.5; 0: none)\n"
               "Prints the series and, last, one JSON line: imu, rms_deg, mean_deg, max_deg, final_deg.\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    usage();
    return 2;
  }
  const std::string sequence_bag = argv[1], outputs_bag = argv[2];
  std::string ns = "/visual_gyro";
  double step = 0.01, print_every = 0.5;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "integrate_imu: %s needs a value\n", a.c_str());
      return 2;
    }
    try {
      if (a == "--ns") ns = argv[++i];
      else if (a == "--step") step = std::stod(argv[++i]);
      else if (a == "--print-every") print_every = std::stod(argv[++i]);
      else {
        std::fprintf(stderr, "integrate_imu: unknown option '%s'\n", a.c_str());
        usage();
        return 2;
      }
    } catch (const std::logic_error&) {
      std::fprintf(stderr, "integrate_imu: bad value for %s\n", a.c_str());
      return 2;
    }
  }
  if (!(step > 0.0)) {
    std::fprintf(stderr, "integrate_imu: --step must be > 0\n");
    return 2;
  }
  namespace ii = visual_gyro::imu_integration;
  try {
    const auto contents = visual_gyro::bag_tools::readSequenceBag(sequence_bag);
    if (contents.poses.size() < 2) {
      std::fprintf(stderr, "integrate_imu: %s has no ground-truth poses to compare with\n", sequence_bag.c_str());
      return 1;
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
      std::fprintf(stderr, "integrate_imu: %s has no messages on %s/imu\n", outputs_bag.c_str(), ns.c_str());
      return 1;
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
    std::printf("{\"imu\": %zu, \"rms_deg\": %.4f, \"mean_deg\": %.4f, \"max_deg\": %.4f, \"final_deg\": %.4f}\n",
                rates.size(), error.rms_deg, error.mean_deg, error.max_deg, error.final_deg);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "integrate_imu: %s\n", e.what());
    return 1;
  }
  return 0;
}
