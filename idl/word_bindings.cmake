# Generates msgs/word_bindings.hpp from the IDL files: for every <name>.idl that declares the four
# structs of a device with a status and a control word (<Name>Status, <Name>StatusWord,
# <Name>ControlWord, <Name>Setpoint), one binding struct naming those types and listing, field by
# field, the word fields the IDL declares. The profile's bit names meet these field names at
# start-up (gateways/codecs/named_bits.hpp), and lb_check_device_types holds the two against each other at
# build time: a bit table is never typed by hand.
#
#   boolean <bit>;      -> a flag: {"<bit>", setter, getter}
#   <Enum> <field>;     -> a code field: the profile's code names match the enumerators' lower-case
#                          tails (PULLER_SPEED_SET_REMOTE -> "remote"); the first enumerator is
#                          what a profile without the field reports
#   boolean <bit>;   // toggle...
#                       -> a toggle: a flag whose every change is the command (CiA 420-4 6020h bit 2,
#                          change of length), flipped by the bridge itself: neither a state the
#                          setpoint carries nor a button, so never momentary
#   momentary           -> the control word's flags the setpoint does not carry and that are no
#                          toggle (pressed like buttons)

# "haul_off" -> "HaulOff"
function(lb_camel_case out name)
  string(REPLACE "_" ";" parts "${name}")
  set(result "")
  foreach(part IN LISTS parts)
    string(SUBSTRING "${part}" 0 1 head)
    string(SUBSTRING "${part}" 1 -1 tail)
    string(TOUPPER "${head}" head)
    string(APPEND result "${head}${tail}")
  endforeach()
  set(${out} "${result}" PARENT_SCOPE)
endfunction()

# Reads one IDL file into variables of the caller: idl_structs, idl_enums, idl_toggles (the flags
# whose comment begins with "toggle"), and per struct idl_struct_<S> ("type:name" items), per enum
# idl_enum_<E> (enumerators).
macro(lb_read_idl file)
  file(READ "${file}" _text)
  string(REPLACE ";" "" _text "${_text}")
  string(REGEX MATCHALL "boolean[ \t]+[a-z_][a-z0-9_]*[ \t]*//[ \t]*toggle" _toggle_lines "${_text}")
  set(idl_toggles "")
  foreach(_line IN LISTS _toggle_lines)
    string(REGEX REPLACE "boolean[ \t]+([a-z_][a-z0-9_]*).*" "\\1" _name "${_line}")
    list(APPEND idl_toggles "${_name}")
  endforeach()
  string(REGEX REPLACE "//[^\n]*" "" _text "${_text}")
  string(REPLACE "\n" ";" _lines "${_text}")
  set(idl_structs "")
  set(idl_enums "")
  set(_in "")
  set(_kind "")
  foreach(_line IN LISTS _lines)
    if(_line MATCHES "struct[ \t]+([A-Za-z_][A-Za-z0-9_]*)")
      set(_in "${CMAKE_MATCH_1}")
      set(_kind struct)
      list(APPEND idl_structs "${_in}")
      set(idl_struct_${_in} "")
    elseif(_line MATCHES "enum[ \t]+([A-Za-z_][A-Za-z0-9_]*)")
      set(_in "${CMAKE_MATCH_1}")
      set(_kind enum)
      list(APPEND idl_enums "${_in}")
      set(idl_enum_${_in} "")
    elseif(_line MATCHES "^[ \t]*}")
      set(_in "")
    elseif(_in AND _kind STREQUAL "struct" AND _line MATCHES "^[ \t]*([A-Za-z_][A-Za-z0-9_]*)[ \t]+([a-z_][a-z0-9_]*)[ \t]*$")
      list(APPEND idl_struct_${_in} "${CMAKE_MATCH_1}:${CMAKE_MATCH_2}")
    elseif(_in AND _kind STREQUAL "enum")
      string(REGEX MATCHALL "[A-Z][A-Z0-9_]*" _names "${_line}")
      list(APPEND idl_enum_${_in} ${_names})
    endif()
  endforeach()
endmacro()

# The longest common prefix of the enumerators, cut after its last '_'.
function(lb_enum_prefix out)
  list(GET ARGN 0 prefix)
  foreach(name IN LISTS ARGN)
    string(LENGTH "${prefix}" n)
    while(n GREATER 0)
      string(SUBSTRING "${name}" 0 ${n} head)
      if(head STREQUAL prefix)
        break()
      endif()
      math(EXPR n "${n} - 1")
      string(SUBSTRING "${prefix}" 0 ${n} prefix)
    endwhile()
  endforeach()
  if(prefix MATCHES "^(.*_)")
    set(prefix "${CMAKE_MATCH_1}")
  else()
    set(prefix "")
  endif()
  set(${out} "${prefix}" PARENT_SCOPE)
endfunction()

# The C++ lines of one word's fields: flags and code fields of struct `word` (set in the caller by
# lb_read_idl). Sets <out>_flags, <out>_codes, <out>_code_functions, <out>_flag_names.
function(lb_word_fields out word alias)
  set(flags "")
  set(codes "")
  set(functions "")
  set(flag_names "")
  foreach(item IN LISTS idl_struct_${word})
    string(REPLACE ":" ";" pair "${item}")
    list(GET pair 0 type)
    list(GET pair 1 name)
    if(type STREQUAL "boolean")
      string(APPEND flags "      {\"${name}\", &${alias}::${name}, &${alias}::${name}},\n")
      list(APPEND flag_names "${name}")
    elseif(type IN_LIST idl_enums)
      set(enumerators ${idl_enum_${type}})
      lb_enum_prefix(prefix ${enumerators})
      list(GET enumerators 0 fallback)
      set(body "    w.${name}(")
      set(get_body "    return ")
      foreach(e IN LISTS enumerators)
        if(NOT e STREQUAL fallback)
          string(LENGTH "${prefix}" n)
          string(SUBSTRING "${e}" ${n} -1 code)
          string(TOLOWER "${code}" code)
          string(APPEND body "code == \"${code}\" ? msg::${e} : ")
          string(APPEND get_body "w.${name}() == msg::${e} ? \"${code}\" : ")
        endif()
      endforeach()
      string(APPEND body "msg::${fallback})")
      string(APPEND get_body "\"\"")
      string(APPEND functions "  static void ${word}_${name}(msg::${word}& w, std::string_view code) {\n${body};\n  }\n")
      string(APPEND functions
             "  static std::string_view ${word}_${name}_code(const msg::${word}& w) {\n${get_body};\n  }\n")
      string(APPEND codes "      {\"${name}\", &${word}_${name}, &${word}_${name}_code},\n")
    endif()
  endforeach()
  set(${out}_flags "${flags}" PARENT_SCOPE)
  set(${out}_codes "${codes}" PARENT_SCOPE)
  set(${out}_code_functions "${functions}" PARENT_SCOPE)
  set(${out}_flag_names "${flag_names}" PARENT_SCOPE)
endfunction()

function(lb_count out)
  list(LENGTH ARGN n)
  set(${out} ${n} PARENT_SCOPE)
endfunction()

# Writes <output> (only when its text changed, so nothing rebuilds for nothing).
function(lb_generate_word_bindings output)
  set(includes "")
  set(bindings "")
  set(names "")
  foreach(file IN LISTS ARGN)
    get_filename_component(idl "${file}" NAME_WE)
    lb_camel_case(P "${idl}")
    lb_read_idl("${file}")
    set(needed ${P}Status ${P}StatusWord ${P}ControlWord ${P}Setpoint)
    set(complete TRUE)
    foreach(s IN LISTS needed)
      if(NOT s IN_LIST idl_structs)
        set(complete FALSE)
      endif()
    endforeach()
    if(NOT complete)
      continue()
    endif()
    lb_word_fields(status ${P}StatusWord StatusWord)
    lb_word_fields(control ${P}ControlWord ControlWord)
    # Momentary: the control word's flags the setpoint does not carry as a state, but its toggles.
    set(momentary "")
    set(toggles "")
    foreach(flag IN LISTS control_flag_names)
      if(flag IN_LIST idl_toggles)
        string(APPEND toggles "\"${flag}\", ")
      elseif(NOT "boolean:${flag}" IN_LIST idl_struct_${P}Setpoint)
        string(APPEND momentary "\"${flag}\", ")
      endif()
    endforeach()
    string(REGEX MATCHALL "\"[a-z0-9_]+\", " m "${momentary}")
    lb_count(n_momentary ${m})
    string(REGEX MATCHALL "\"[a-z0-9_]+\", " t "${toggles}")
    lb_count(n_toggles ${t})
    string(REGEX MATCHALL "{\"" sf "${status_flags}")
    lb_count(n_status_flags ${sf})
    string(REGEX MATCHALL "{\"" cf "${control_flags}")
    lb_count(n_control_flags ${cf})
    string(REGEX MATCHALL "{\"" sc "${status_codes}")
    lb_count(n_status_codes ${sc})
    string(REGEX MATCHALL "{\"" cc "${control_codes}")
    lb_count(n_control_codes ${cc})
    string(APPEND includes "#include \"msgs/${idl}.h\"\n#include \"msgs/${idl}PubSubTypes.h\"\n")
    list(APPEND names ${P})
    string(APPEND bindings "
// ${idl}.idl
struct ${P} {
  static constexpr std::string_view idl = \"${idl}\";
  using Status = msg::${P}Status;
  using StatusWord = msg::${P}StatusWord;
  using ControlWord = msg::${P}ControlWord;
  using Setpoint = msg::${P}Setpoint;
  using StatusTopic = msg::${P}StatusPubSubType;
  using SetpointTopic = msg::${P}SetpointPubSubType;

${status_code_functions}${control_code_functions}
  static constexpr std::array<FlagField<StatusWord>, ${n_status_flags}> status_flags{{
${status_flags}  }};
  static constexpr std::array<CodeField<StatusWord>, ${n_status_codes}> status_codes{{
${status_codes}  }};
  static constexpr std::array<FlagField<ControlWord>, ${n_control_flags}> control_flags{{
${control_flags}  }};
  static constexpr std::array<CodeField<ControlWord>, ${n_control_codes}> control_codes{{
${control_codes}  }};
  static constexpr std::array<std::string_view, ${n_momentary}> momentary{${momentary}};
  static constexpr std::array<std::string_view, ${n_toggles}> toggles{${toggles}};
};
")
  endforeach()
  string(REPLACE ";" ", " name_list "${names}")
  set(text "#pragma once
// Generated by idl/word_bindings.cmake from the IDL files: do not edit. One binding per IDL file
// that declares a device with a status word and a control word.

#include <array>
#include <string_view>
#include <tuple>

${includes}
namespace linebridge_msgs::bindings {

namespace msg = linebridge_msgs::msg;

// One boolean field of a word: the profile bit of the same name sets it.
template <class W>
struct FlagField {
  std::string_view name;
  void (W::*set)(bool);
  bool (W::*get)() const;
};

// One enumerated field of a word: set from the name the profile gives the field's code (empty:
// the profile has no such field); get gives that name back (\"\" for the first enumerator, what a
// profile without the field reports).
template <class W>
struct CodeField {
  std::string_view name;
  void (*set)(W&, std::string_view code);
  std::string_view (*get)(const W&);
};
${bindings}
using All = std::tuple<${name_list}>;

// Calls f.template operator()<B>() for the binding of IDL file `idl`; false when there is none.
template <class F>
bool visit(std::string_view idl, F&& f) {
  return std::apply([&]<class... B>(B...) { return ((B::idl == idl ? (f.template operator()<B>(), true) : false) || ...); },
                    All{});
}

}  // namespace linebridge_msgs::bindings
")
  file(WRITE "${output}.new" "${text}")
  file(COPY_FILE "${output}.new" "${output}" ONLY_IF_DIFFERENT)
  file(REMOVE "${output}.new")
endfunction()
