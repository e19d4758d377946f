#pragma once

#include <stdexcept>
#include <string>
#include <utility>

#include "base/result.hpp"

namespace lb::gateways {

// For start-up only (a writer, reader or service that cannot be created): a gateway that cannot
// offer its topics must not start, so the error becomes the exception that ends start-up.
template <class T>
T checked(Result<T> r, const std::string& what) {
  if (!r) throw std::runtime_error(what + ": " + r.error().message);
  return std::move(*r);
}

}  // namespace lb::gateways
