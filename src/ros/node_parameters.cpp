#include "node_parameters.h"

#include <algorithm>

#include <ros/console.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {

namespace {

/// A parameter's value as the text the settings tables parse; "" or why it has no such text.
std::string parameterText(XmlRpc::XmlRpcValue& value, std::string* text) {
  switch (value.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean: *text = static_cast<bool>(value) ? "true" : "false"; return "";
    case XmlRpc::XmlRpcValue::TypeInt: *text = std::to_string(static_cast<int>(value)); return "";
    case XmlRpc::XmlRpcValue::TypeDouble: *text = SettingSpec::formatNumber(static_cast<double>(value)); return "";
    case XmlRpc::XmlRpcValue::TypeString: *text = static_cast<std::string>(value); return "";
    case XmlRpc::XmlRpcValue::TypeArray: {
      std::vector<std::string> items;
      for (int i = 0; i < value.size(); ++i) {
        std::string item;
        const XmlRpc::XmlRpcValue::Type type = value[i].getType();
        if (type != XmlRpc::XmlRpcValue::TypeInt && type != XmlRpc::XmlRpcValue::TypeDouble) {
          *text = value.toXml();
          return "a list of numbers may hold numbers only";
        }
        parameterText(value[i], &item);
        items.push_back(item);
      }
      *text = "[" + SettingSpec::joined(items, ", ") + "]";
      return "";
    }
    default: *text = value.toXml(); return "not a number, text, boolean or list";
  }
}

/// `text` (accepted by the setting) as a parameter of the setting's type.
XmlRpc::XmlRpcValue typedValue(SettingType type, const std::string& text) {
  switch (type) {
    case SettingType::kBool: return XmlRpc::XmlRpcValue(text == "true" || text == "1" || text == "True" ||
                                                        text == "on" || text == "yes");
    case SettingType::kInt: return XmlRpc::XmlRpcValue(static_cast<int>(std::stoll(text)));
    case SettingType::kDouble: return XmlRpc::XmlRpcValue(std::stod(text));
    case SettingType::kString: return XmlRpc::XmlRpcValue(text);
    case SettingType::kDoubleList: {
      std::vector<double> values;
      setting_detail::parseRealList(text, &values);
      XmlRpc::XmlRpcValue list;
      list.setSize(static_cast<int>(values.size()));
      for (size_t i = 0; i < values.size(); ++i) list[static_cast<int>(i)] = values[i];
      return list;
    }
  }
  return XmlRpc::XmlRpcValue();
}

}  // namespace

NodeParameters NodeParameters::read(const ros::NodeHandle& pnh) {
  NodeParameters p;
  // The pipeline's settings reach the node through dynamic_reconfigure; only the backend is kept.
  VisualGyroSettings pipeline;
  std::vector<std::string> refused;
  for (const AnySetting& setting : everySetting()) {
    const std::string& name = setting.spec->name;
    XmlRpc::XmlRpcValue raw;
    if (!pnh.getParam(name, raw)) continue;  // absent: the default
    std::string text;
    std::string why = parameterText(raw, &text);
    if (!why.empty()) {
      why = name + ": " + why + ", got " + text;
    } else {
      why = setting.node ? applyNodeSetting(&p, name, text) : applySetting(&pipeline, name, text);
    }
    if (why.empty()) {
      const XmlRpc::XmlRpcValue typed = typedValue(setting.spec->type, text);
      if (raw.getType() != typed.getType() || raw.getType() == XmlRpc::XmlRpcValue::TypeArray)
        pnh.setParam(name, typed);
      continue;
    }
    ROS_ERROR("visual_gyro: start-up parameter ~%s refused (%s); using its default %s", name.c_str(), why.c_str(),
              setting.default_text.empty() ? "\"\"" : setting.default_text.c_str());
    refused.push_back("start-up parameter " + why);
    pnh.setParam(name, typedValue(setting.spec->type, setting.default_text));
  }
  p.backend = findSetting("backend")->text(pipeline);
  p.plot.frame_id = p.world_frame;
  p.refused = SettingSpec::joined(refused, "; ");
  return p;
}

bool NodeParameters::cameraFor(int width, int height, CameraModel* camera, std::string* why) const {
  const double fx_used = fx;
  const double fy_used = fy > 0.0 ? fy : fx;
  const double cx_used = cx >= 0.0 ? cx : (width - 1) / 2.0;
  const double cy_used = cy >= 0.0 ? cy : (height - 1) / 2.0;
  DistortionModel model = DistortionModel::kNone;
  if (!parseDistortionModel(distortion_model, &model)) {
    std::string accepted;
    for (const std::string& name : findNodeSetting("distortion_model")->choices)
      accepted += (accepted.empty() ? "" : ", ") + name;
    *why = "~distortion_model '" + distortion_model + "' is not supported (" + accepted + ")";
    return false;
  }
  if (!(fx_used > 0.0)) {
    *why = "~use_camera_info is false but ~fx is not set (give ~fx, ~fy, ~cx, ~cy)";
    return false;
  }
  std::vector<double> d = D;
  if (std::all_of(d.begin(), d.end(), [](double v) { return v == 0.0; })) {
    d.clear();
    model = DistortionModel::kNone;
  }
  *camera = CameraModel(fx_used, fy_used, cx_used, cy_used, width, height, model, d);
  return true;
}

}  // namespace visual_gyro
