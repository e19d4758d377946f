# Script mode: writes a C++ source that holds text files as string literals.
#   cmake -DOUTPUT=x.cpp -DHEADER=a/b.hpp -DNAMESPACE=lb::x -DFUNCTION=f -DFILES="a;b" -P embed_texts.cmake
set(entries "")
foreach(file IN LISTS FILES)
  file(READ "${file}" text)
  get_filename_component(name "${file}" NAME)
  string(APPEND entries "    {\"${name}\", R\"lbembed(${text})lbembed\"},\n")
endforeach()
file(WRITE "${OUTPUT}.tmp"
"// Generated from ${FILES}: do not edit.
#include \"${HEADER}\"

namespace ${NAMESPACE} {
namespace {
constexpr std::pair<std::string_view, std::string_view> kTexts[] = {
${entries}};
}  // namespace

std::span<const std::pair<std::string_view, std::string_view>> ${FUNCTION}() { return kTexts; }

}  // namespace ${NAMESPACE}
")
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
