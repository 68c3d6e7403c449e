// Unit conversions: radians inside the math, arcsec at interfaces, counts for the sensor.
#pragma once
#include <numbers>

namespace fpss {

inline constexpr double kArcsecPerRad = 180.0 * 3600.0 / std::numbers::pi;
inline constexpr double kRadPerArcsec = 1.0 / kArcsecPerRad;
inline constexpr double kArcsecPerDeg = 3600.0;
inline constexpr double kMasPerArcsec = 1000.0;

inline constexpr double arcsec_to_rad(double arcsec) { return arcsec * kRadPerArcsec; }
inline constexpr double rad_to_arcsec(double rad) { return rad * kArcsecPerRad; }
inline constexpr double deg_to_arcsec(double deg) { return deg * kArcsecPerDeg; }

// The sensor's digital output is a signed 15-bit range over the 1 deg field (Gambardella and Thompson, 1980, Table 2 footnote a: 0.109866 arcsec/count).
inline constexpr double kCountsMin = -32768.0;
inline constexpr double kCountsMax = 32767.0;

}  // namespace fpss
