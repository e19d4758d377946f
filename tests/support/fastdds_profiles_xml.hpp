#pragma once
// A Fast DDS XML profiles file (a site's profiles_file) made of the profiles a test gives, so the
// test spells out only the QoS it is about.

#include <string>

namespace lb::test {

// <data_writer profile_name="..."> with the given QoS elements (the inside of <qos>).
inline std::string data_writer_profile(const std::string& name, const std::string& qos) {
  return "  <data_writer profile_name=\"" + name + "\">\n    <qos>" + qos + "</qos>\n  </data_writer>\n";
}

inline std::string fastdds_profiles_xml(const std::string& profiles) {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n"
         "<dds xmlns=\"http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles\"><profiles>\n" +
         profiles + "</profiles></dds>\n";
}

}  // namespace lb::test
