#include "profiles/yaml_structure.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/parser.h>
#include <yaml-cpp/yaml.h>

#include <sstream>
#include <unordered_map>
#include <vector>

#include "profiles/yaml_source.hpp"

namespace lb::profiles {
namespace {

std::string place(const std::string& source, const YAML::Mark& mark) {
  return source + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

class StructureCheck final : public YAML::EventHandler {
 public:
  StructureCheck(const std::string& source, const YamlLimits& limits) : source_(source), limits_(limits) {}

  void OnDocumentStart(const YAML::Mark& mark) override {
    // YAML::Load reads the first document only: a second one would be ignored without a word.
    if (++documents_ > 1) fail(mark, "a configuration file holds one YAML document (a second one starts here)");
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t anchor) override {
    key(mark, nullptr);
    leaf(mark, anchor);
  }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t anchor) override {
    if (in_key_position()) fail(mark, "a key must be a plain value, not an alias");
    const auto it = anchor_nodes_.find(anchor);
    add_nodes(mark, it == anchor_nodes_.end() ? 1 : it->second);
    value_done();
  }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t anchor, const std::string& value) override {
    key(mark, &value);
    leaf(mark, anchor);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t anchor,
                       YAML::EmitterStyle::value) override {
    open(mark, anchor, false);
  }
  void OnSequenceEnd() override { close(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t anchor,
                  YAML::EmitterStyle::value) override {
    open(mark, anchor, true);
  }
  void OnMapEnd() override { close(); }

 private:
  struct Key {
    std::size_t line, column;
  };
  struct Container {
    bool map;
    YAML::anchor_t anchor;
    std::size_t nodes_at_start;
    bool expecting_key = true;                  // maps: the next node is a key
    std::unordered_map<std::string, Key> keys;  // maps: the keys so far, where each was
  };

  [[noreturn]] void fail(const YAML::Mark& mark, const std::string& what) const {
    throw ConfigError(place(source_, mark) + ": " + what);
  }

  bool in_key_position() const { return !stack_.empty() && stack_.back().map && stack_.back().expecting_key; }

  // A node in key position must be a plain value given once; any other node is a value.
  void key(const YAML::Mark& mark, const std::string* text) {
    if (!in_key_position()) {
      value_done();
      return;
    }
    if (text == nullptr) fail(mark, "a key must not be empty");
    auto& c = stack_.back();
    const auto [it, added] = c.keys.try_emplace(*text, Key{static_cast<std::size_t>(mark.line) + 1,
                                                           static_cast<std::size_t>(mark.column) + 1});
    if (!added) {
      fail(mark, "key '" + *text + "' is given twice in this mapping (first at line " +
                     std::to_string(it->second.line) + ", column " + std::to_string(it->second.column) + ")");
    }
    c.expecting_key = false;
  }

  // After a complete value: a map expects its next key.
  void value_done() {
    if (!stack_.empty() && stack_.back().map) stack_.back().expecting_key = true;
  }

  void leaf(const YAML::Mark& mark, YAML::anchor_t anchor) {
    if (anchor != 0) anchor_nodes_[anchor] = 1;
    add_nodes(mark, 1);
  }

  void add_nodes(const YAML::Mark& mark, std::size_t n) {
    nodes_ += n;
    if (nodes_ > limits_.max_nodes) {
      fail(mark, "the document has more than " + std::to_string(limits_.max_nodes) + " values (aliases expanded)");
    }
  }

  void open(const YAML::Mark& mark, YAML::anchor_t anchor, bool map) {
    if (in_key_position()) fail(mark, std::string("a key must be a plain value, not a ") + (map ? "mapping" : "list"));
    if (stack_.size() >= limits_.max_depth) {
      fail(mark, "nested more than " + std::to_string(limits_.max_depth) + " levels deep");
    }
    add_nodes(mark, 1);
    stack_.push_back(Container{map, anchor, nodes_, true, {}});
  }

  void close() {
    const Container c = std::move(stack_.back());
    stack_.pop_back();
    if (c.anchor != 0) anchor_nodes_[c.anchor] = nodes_ - c.nodes_at_start + 1;
    value_done();
  }

  const std::string& source_;
  const YamlLimits& limits_;
  std::vector<Container> stack_;
  std::unordered_map<YAML::anchor_t, std::size_t> anchor_nodes_;  // nodes an alias of it adds
  std::size_t nodes_ = 0;
  int documents_ = 0;
};

}  // namespace

void check_yaml_structure(const std::string& text, const std::string& source, const YamlLimits& limits) {
  std::istringstream in(text);
  try {
    YAML::Parser parser(in);
    StructureCheck check(source, limits);
    while (parser.HandleNextDocument(check)) {
    }
  } catch (const YAML::ParserException& e) {
    throw ConfigError(place(source, e.mark) + ": YAML syntax error: " + e.msg);
  }
}

}  // namespace lb::profiles
