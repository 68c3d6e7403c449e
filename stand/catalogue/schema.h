// The catalogue's schema, one text for both backends as versioned migrations.
#pragma once
#include <string>

namespace fpss::schema {

enum class Dialect { sqlite, postgres };

// The SQL that takes a catalogue from schema version `step` to `step` + 1, as `dialect` spells it.
std::string migration(int step, Dialect dialect);

}  // namespace fpss::schema
