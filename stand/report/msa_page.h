// The measurement-system analysis as a page (fpss-stand msa --report).
#pragma once
#include <string>

#include "stand/catalogue/msa_study.h"

namespace fpss {

// A self-contained page: the study's design, then per quantity its variance components, %GRR and
// ndc with AIAG's reading; every text escaped.
std::string msa_html(const MsaStudy& s, const std::string& catalogue);

}  // namespace fpss
