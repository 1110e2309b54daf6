// The test programs' precompiled header (issue #51, tests/CMakeLists.txt): the library headers
// most of the ~150 test files parse, compiled once instead of once per file. Only headers from
// outside the repository, so that changing a project header rebuilds only the tests that include
// it. Every test file still includes what it uses; this file is force-included before it.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>
