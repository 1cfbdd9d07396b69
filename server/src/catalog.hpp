// The models this server animates with: the built-in one (the default) and any
// loaded with `--model NAME=FILE`, each with the built-in phone sets that
// resolve against its phoneme inventory and the evaluator's tables. Built once at start-up, read-only
// afterwards, so every call can share it without locking.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/coarticulation.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/server/config.hpp"

namespace lipsync::server {

struct ModelEntry {
  std::string name;
  const ArticulationModel* model = nullptr;
  std::unique_ptr<ArticulationModel> owned;
  /// The evaluator's tables for `model`, built once and shared by every stream.
  std::shared_ptr<const CoarticulationTables> tables;
  std::vector<PhoneSet> phone_sets;
  bool is_default = false;

  const PhoneSet* find_phone_set(std::string_view name) const;
};

class ModelCatalog {
 public:
  /// Loads and validates every file; throws InputError naming the file and field.
  explicit ModelCatalog(const std::vector<ModelFile>& files);

  /// The model of that name; "" is the default. nullptr if there is none.
  const ModelEntry* find(std::string_view name) const;
  const std::vector<std::unique_ptr<ModelEntry>>& entries() const { return entries_; }
  std::string names() const;

 private:
  std::vector<std::unique_ptr<ModelEntry>> entries_;
};

}  // namespace lipsync::server
