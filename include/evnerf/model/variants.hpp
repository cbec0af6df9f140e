// model/variants.hpp — a list of model types under the names programs know them by: the variants a command line
// (cli/cli.hpp) or a Python module (python/module.hpp) is built with, the dispatch from a name to its type,
// and the pick of the variant that can load a checkpoint. Depends on io/checkpoint.hpp (and, through its
// templates, on the model types it is given).
#pragma once
#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <string>

#include "../core/error.hpp"
#include "../io/checkpoint.hpp"

namespace evnerf {

/// A string usable as a template argument (a variant's name).
template <std::size_t N>
struct Name {
  char s[N]{};
  constexpr Name(const char (&a)[N]) { std::copy_n(a, N, s); }
};

/// A model type and the name the command line knows it by.
template <class Model, Name N>
struct Variant {
  using model = Model;
  static constexpr const char* name = N.s;
};

/// Calls fn.template operator()<Model>(name) for the variant called `name`.
template <class... V, class Fn>
int with_variant(const std::string& name, Fn&& fn) {
  int result = 0;
  const bool found = ((name == V::name ? (result = fn.template operator()<typename V::model>(std::string(V::name)), true) : false) || ...);
  if (!found) {
    std::string known;
    ((known += (known.empty() ? "" : ", ") + std::string(V::name)), ...);
    throw Error("unknown variant '" + name + "' (this program has: " + known + ")");
  }
  return result;
}

/// The variant that can load a checkpoint: of those whose architecture, loss and parameter count match the
/// file, the one named in the file, else the first (a file written under another name, or by another
/// program with the same model).
template <class... V>
std::string checkpoint_variant(const std::filesystem::path& path) {
  const auto h = io::peek_checkpoint(path);
  auto fits = [&]<class Model>() {
    return h.n_params == Model::renderer_type::n_params + 2 * h.n_slices && h.loss == Model::loss_description() &&
           h.architecture == Model::architecture();
  };
  std::string pick;
  ((pick.empty() && h.name == V::name && fits.template operator()<typename V::model>() ? (pick = V::name, 0) : 0), ...);
  ((pick.empty() && fits.template operator()<typename V::model>() ? (pick = V::name, 0) : 0), ...);
  if (pick.empty())
    throw Error(path.string(), 0,
                "written by variant '" + h.name + "' with the loss '" + h.loss + "'" + " and the architecture '" + h.architecture + "'" +
                    ", which no variant of this program matches");
  return pick;
}

}  // namespace evnerf
