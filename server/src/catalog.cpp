#include "catalog.hpp"

#include <fstream>
#include <sstream>

#include "lipsync/error.hpp"

namespace lipsync::server {
namespace {

std::vector<PhoneSet> phone_sets_for(const ArticulationModel& model) {
  std::vector<PhoneSet> sets;
  for (const std::string& set_name : PhoneSet::builtin_names()) {
    try {
      if (auto set = PhoneSet::builtin(set_name, model)) sets.push_back(std::move(*set));
    } catch (const InputError&) {
      // This table names a phoneme the model lacks: the model does not speak it.
    }
  }
  return sets;
}

}  // namespace

const PhoneSet* ModelEntry::find_phone_set(std::string_view set_name) const {
  for (const PhoneSet& set : phone_sets) {
    if (set.name() == set_name) return &set;
  }
  return nullptr;
}

ModelCatalog::ModelCatalog(const std::vector<ModelFile>& files) {
  auto builtin = std::make_unique<ModelEntry>();
  builtin->model = &ArticulationModel::builtin();
  builtin->name = builtin->model->name();
  builtin->phone_sets = phone_sets_for(*builtin->model);
  builtin->tables = std::make_shared<const CoarticulationTables>(*builtin->model);
  builtin->is_default = true;
  entries_.push_back(std::move(builtin));
  for (const ModelFile& file : files) {
    if (find(file.name)) throw InputError(file.path, 0, "model name '" + file.name + "' is already taken");
    std::ifstream in(file.path);
    if (!in) throw InputError(file.path, 0, "cannot open the model file");
    std::stringstream text;
    text << in.rdbuf();
    auto entry = std::make_unique<ModelEntry>();
    entry->owned = std::make_unique<ArticulationModel>(ArticulationModel::from_json(text.str(), file.path));
    entry->model = entry->owned.get();
    entry->name = file.name;
    entry->phone_sets = phone_sets_for(*entry->model);
    entry->tables = std::make_shared<const CoarticulationTables>(*entry->model);
    entries_.push_back(std::move(entry));
  }
}

const ModelEntry* ModelCatalog::find(std::string_view name) const {
  if (name.empty()) return entries_.front().get();
  for (const auto& entry : entries_) {
    if (entry->name == name) return entry.get();
  }
  return nullptr;
}

std::string ModelCatalog::names() const {
  std::string out;
  for (const auto& entry : entries_) out += (out.empty() ? "" : ", ") + entry->name;
  return out;
}

}  // namespace lipsync::server
