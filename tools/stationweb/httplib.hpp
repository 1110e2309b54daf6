#pragma once
// cpp-httplib for stationweb and its tests, without glibc's `_res` macro: httplib.h includes
// <resolv.h>, whose `#define _res (*__res_state())` turns Eigen's parameters named _res into
// syntax errors in any header included after it (db/history/repository.hpp includes Eigen).
// httplib.h itself does not use the name.
#include <httplib.h>
#undef _res
