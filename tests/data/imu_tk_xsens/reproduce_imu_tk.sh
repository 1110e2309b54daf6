#!/usr/bin/env bash
# reproduce_imu_tk.sh -- the peer tool's own calibration of its own data, reproduced.
#
# What this is
#   IMU-TK (Inertial Measurement Unit Toolkit, by Alberto Pretto et al., BSD licence,
#   Copyright (c) 2014 Alberto Pretto <pretto@diag.uniroma1.it>; see LICENSE next to this
#   script) ships an example, apps/test_imu_calib.cpp, that calibrates the accelerometer and
#   gyroscope triads of its own Xsens test recording (bin/test_data/xsens_acc.mat,
#   xsens_gyro.mat -- the same files as xsens_*.mat.xz here) with its multi-position method
#   (Tedaldi, Pretto, Menegatti, ICRA 2014). This script rebuilds that example from IMU-TK's
#   source (commit 7780270fb9a227c79323199303f23989e689a89d) WITHOUT its Qt/OpenGL
#   visualisation, runs it on the recording stored next to this script, and writes
#   imu_tk_result.txt (the format of the file of that name in this directory), so that
#   our calibration can be compared with the peer's on the same data.
#
# Usage
#   reproduce_imu_tk.sh [IMU_TK_GIT_DIR [OUT_DIR]]
#     IMU_TK_GIT_DIR  a (bare) git repository of IMU-TK holding commit 7780270
#                     (default /work/.mirror/Kyle-ak+imu_tk/repo)
#     OUT_DIR         where to extract, build and run (default: a new mktemp -d directory);
#                     must not already contain an imu_tk/ directory.
#   Environment: CXX (default g++), EIGEN_INC (default /usr/include/eigen3),
#                IMU_TK_RESULT_DATE (date written in the result header; default today, UTC).
#   Needs: git, tar, xz, sha256sum, awk, a C++17 compiler, Eigen 3, Ceres (+glog, gflags).
#   Output: OUT_DIR/imu_tk_result.txt (also printed), OUT_DIR/run/console.log (IMU-TK's console
#   output, printed with 17 significant digits), OUT_DIR/run/test_imu_acc.calib and
#   test_imu_gyro.calib (IMU-TK's own save(), 6 significant digits), OUT_DIR/run/imu_tk_values.txt,
#   OUT_DIR/imu_tk_changes.diff (every change made to IMU-TK's files).
#
# Every change made to IMU-TK, and why (nothing that affects the numbers is changed: initial
# guesses -- acc bias 32768 counts, gyro scale 1/6258 --, gravity 9.81744, initial static
# interval 50 s, static-interval detector and its threshold sweep, 100 samples per interval,
# acc_use_means=false, gyro timestamps for dt, no gyro-bias optimisation, verbose output on,
# Ceres options, are all exactly as shipped):
#   1. Build: IMU-TK's CMakeLists.txt requires Qt4, OpenGL, GLUT and Boost (all only for the
#      visualisation), so only src/calibration.cpp, src/filters.cpp, src/io_utils.cpp and
#      apps/test_imu_calib.cpp are compiled, by hand, with "$CXX -std=c++17 -O3 -DNDEBUG"
#      (-O3 -DNDEBUG is what IMU-TK's CMake Release default uses) against the installed
#      Ceres/Eigen. src/visualization.cpp and src/vis_extra/* are not built.
#   2. include/imu_tk/visualization.h is replaced (via the include path, the file itself is
#      untouched) by a stub in OUT_DIR/stub/imu_tk/visualization.h whose Plot::plotSamples,
#      Plot::plotIntervals and waitForKey() do nothing. src/calibration.cpp and
#      apps/test_imu_calib.cpp include that header; with verbose output on,
#      calibrateAcc() plots the calibrated accelerations in a Qt window and waits for a key
#      press -- display only, after the accelerometer result is fixed. No .cpp is changed for this.
#   3. include/imu_tk/calibration.h: three setters declared non-void had no return statement
#      (setInitStaticIntervalDuration, setIntarvalsNumSamples, enableGyroBiasOptimization).
#      Flowing off the end of a non-void function is undefined behaviour; built with g++ 12
#      -O3 the unpatched example crashes (SIGSEGV, exit 139) right after reading the data,
#      at its call of setInitStaticIntervalDuration(50.0). Fix: each now returns the value it
#      has just stored ("return init_interval_duration_;" etc.); the stored values are unchanged.
#   4. apps/test_imu_calib.cpp (output only, after/around the unchanged calibration code):
#      a. "std::cout.precision(17);" at the start of main, so that IMU-TK's own console
#         figures (per-threshold residuals, chosen residual, matrices, inverse scales) are
#         printed with 17 significant digits instead of 6;
#      b. "#include <cstdio>" and, just before "return 0;", a block that writes
#         imu_tk_values.txt: the final misalignment matrices (row-major), scale diagonals and
#         bias vectors of both triads with printf("%.17g"), read through IMU-TK's public
#         getters. The 6-digit .calib files are still written by IMU-TK's own save().
#   No Ceres API change was needed (installed Ceres 2.1 accepts the code as is). The compiler
#   still warns about member-initialiser order in base.h (-Wreorder, harmless); left as is.
set -euo pipefail

MIRROR=${1:-/work/.mirror/Kyle-ak+imu_tk/repo}
OUT=${2:-$(mktemp -d -t imu_tk_repro.XXXXXX)}
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
COMMIT=7780270fb9a227c79323199303f23989e689a89d
CXX=${CXX:-g++}
EIGEN_INC=${EIGEN_INC:-/usr/include/eigen3}
CXXFLAGS=(-std=c++17 -O3 -DNDEBUG)
RESULT_DATE=${IMU_TK_RESULT_DATE:-$(date -u +%F)}

die() { echo "reproduce_imu_tk.sh: error: $*" >&2; exit 1; }
t_start=$(date +%s.%N)

mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
SRC=$OUT/imu_tk
[ ! -e "$SRC" ] || die "$SRC already exists; give an empty or new output directory"
echo "== output directory: $OUT"

# ---------------------------------------------------------------- 1. extract IMU-TK
git -C "$MIRROR" cat-file -e "$COMMIT^{commit}" 2>/dev/null || die "commit $COMMIT not in $MIRROR"
mkdir -p "$SRC" "$OUT/orig"
git -C "$MIRROR" archive "$COMMIT" | tar -x -C "$SRC"
git -C "$MIRROR" archive "$COMMIT" include/imu_tk/calibration.h apps/test_imu_calib.cpp \
  | tar -x -C "$OUT/orig"
echo "== extracted IMU-TK $COMMIT into $SRC"

# ---------------------------------------------------------------- 2. patches
# Change 3: missing return statements in calibration.h.
H=$SRC/include/imu_tk/calibration.h
sed -i \
  -e 's/{ init_interval_duration_ = duration; };/{ init_interval_duration_ = duration; return init_interval_duration_; };/' \
  -e 's/{ interval_n_samples_ = num; };/{ interval_n_samples_ = num; return interval_n_samples_; };/' \
  -e 's/{ optimize_gyro_bias_ = enabled; };/{ optimize_gyro_bias_ = enabled; return optimize_gyro_bias_; };/' \
  "$H"
[ "$(grep -c -e '= duration; return init_interval_duration_; };' -e '= num; return interval_n_samples_; };' \
       -e '= enabled; return optimize_gyro_bias_; };' "$H")" = 3 ] || die "calibration.h patch did not apply"

# Change 2: no-op visualisation header, found before IMU-TK's own include directory.
mkdir -p "$OUT/stub/imu_tk"
cat > "$OUT/stub/imu_tk/visualization.h" <<'EOF'
// Stub for IMU-TK's Qt/OpenGL include/imu_tk/visualization.h (added by reproduce_imu_tk.sh):
// plotting and waiting for a key press do nothing. Vis3D (unused by the calibration) is omitted.
#pragma once
#include <vector>
#include "imu_tk/base.h"
namespace imu_tk
{
class Plot
{
public:
  template <typename _T> void plotSamples( const std::vector< TriadData_<_T> > &,
                                           DataInterval = DataInterval() ) {}
  template <typename _T> void plotIntervals( const std::vector< TriadData_<_T> > &,
                                             const std::vector< DataInterval > &,
                                             DataInterval = DataInterval() ) {}
};
inline void waitForKey() {}
}
EOF

# Change 4: output-only additions to the example.
APP=$SRC/apps/test_imu_calib.cpp
cat > "$OUT/dump_block.inc" <<'EOF'
  // [repro] Full-precision dump of the final parameters, in addition to the
  // 6-digit .calib files above (reads the results only, changes nothing).
  {
    FILE *f = std::fopen( "imu_tk_values.txt", "w" );
    if( !f ) return 1;
    const CalibratedTriad *calib[2] = { &mp_calib.getAccCalib(), &mp_calib.getGyroCalib() };
    const char *name[2] = { "acc", "gyro" };
    for( int k = 0; k < 2; k++ )
    {
      const Matrix3d &T = calib[k]->getMisalignmentMatrix(), &K = calib[k]->getScaleMatrix();
      const Vector3d &b = calib[k]->getBiasVector();
      std::fprintf( f, "%s_misalignment", name[k] );
      for( int r = 0; r < 3; r++ )
        for( int c = 0; c < 3; c++ )
          std::fprintf( f, " %.17g", T(r,c) );
      std::fprintf( f, "\n%s_scale %.17g %.17g %.17g\n", name[k], K(0,0), K(1,1), K(2,2) );
      std::fprintf( f, "%s_bias %.17g %.17g %.17g\n", name[k], b(0), b(1), b(2) );
    }
    std::fclose( f );
  }

EOF
awk -v blk="$OUT/dump_block.inc" '
  $0 == "#include <iostream>" {
    print; print "#include <cstdio> // [repro] for the full-precision dump below"; n1++; next }
  $0 == "  vector< TriadData > acc_data, gyro_data;" {
    print "  std::cout.precision(17); // [repro] full-precision console output (formatting only)"
    print ""; print; n2++; next }
  $0 == "  return 0;" {
    while ((getline line < blk) > 0) print line
    print; n3++; next }
  { print }
  END { if (n1 != 1 || n2 != 1 || n3 != 1) exit 1 }' "$APP" > "$APP.new" \
  || die "test_imu_calib.cpp patch did not apply"
mv "$APP.new" "$APP"

( cd "$OUT"
  diff -u orig/include/imu_tk/calibration.h imu_tk/include/imu_tk/calibration.h || true
  diff -u orig/apps/test_imu_calib.cpp imu_tk/apps/test_imu_calib.cpp || true
  diff -u /dev/null stub/imu_tk/visualization.h || true ) > "$OUT/imu_tk_changes.diff"
echo "== patched (see $OUT/imu_tk_changes.diff)"

# ---------------------------------------------------------------- 3. compile (no visualisation)
B=$OUT/build
mkdir -p "$B"
for f in src/calibration.cpp src/filters.cpp src/io_utils.cpp apps/test_imu_calib.cpp; do
  echo "== $CXX ${CXXFLAGS[*]} -c $f"
  "$CXX" "${CXXFLAGS[@]}" -I"$OUT/stub" -I"$SRC/include" -I"$EIGEN_INC" \
    -c "$SRC/$f" -o "$B/$(basename "$f" .cpp).o"
done
"$CXX" -o "$B/test_imu_calib" "$B/calibration.o" "$B/filters.o" "$B/io_utils.o" \
  "$B/test_imu_calib.o" -lceres -lglog -lgflags -lpthread
echo "== built $B/test_imu_calib"

# ---------------------------------------------------------------- 4. data
D=$OUT/data
mkdir -p "$D"
xz -dc "$HERE/xsens_acc.mat.xz" > "$D/xsens_acc.mat"
xz -dc "$HERE/xsens_gyro.mat.xz" > "$D/xsens_gyro.mat"
( cd "$D" && sha256sum -c "$HERE/SHA256SUMS" ) || die "decompressed data do not match SHA256SUMS"
# Cross-check against the copy inside IMU-TK itself.
cmp -s "$D/xsens_acc.mat" "$SRC/bin/test_data/xsens_acc.mat" \
  && cmp -s "$D/xsens_gyro.mat" "$SRC/bin/test_data/xsens_gyro.mat" \
  || die "data differ from IMU-TK's bin/test_data"
n_acc=$(wc -l < "$D/xsens_acc.mat"); n_gyro=$(wc -l < "$D/xsens_gyro.mat")

# ---------------------------------------------------------------- 5. run
R=$OUT/run
mkdir -p "$R"
echo "== running test_imu_calib (as IMU-TK's example: acc file, gyro file)"
t_run0=$(date +%s.%N)
( cd "$R" && "$B/test_imu_calib" "$D/xsens_acc.mat" "$D/xsens_gyro.mat" ) > "$R/console.log" 2>&1 \
  || { cat "$R/console.log"; die "test_imu_calib failed"; }
t_run1=$(date +%s.%N)
grep -q "Better calibration obtained" "$R/console.log" || die "no accelerometer calibration (see $R/console.log)"
grep -q "Gyroscopes calibration: residual" "$R/console.log" || die "no gyroscope calibration"
[ "$(wc -l < "$R/imu_tk_values.txt")" = 6 ] || die "imu_tk_values.txt incomplete"

# ---------------------------------------------------------------- 6. result file
# IMU-TK's own figures, parsed from its console output.
figures=$(awk '
  /^Accelerometers calibration: extracted [0-9]+ intervals using threshold multiplier/ {
    k = $9; ths = ths " " k; nint[k] = $4; cost[k] = "nan"; cur = k }
  /^residual / { cost[cur] = $2 }
  /^Accelerometers calibration: Better calibration obtained using threshold multiplier/ {
    best = $9; best_cost = $12 }
  /^Gyroscopes calibration: calibrating/ { gyro = 1 }
  gyro && /^Residual blocks / { gblocks = $3 }
  gyro && /^Initial / { ginit = $2 }
  gyro && /^Minimizer iterations / { giter = $3 }
  gyro && /^Termination:/ { gterm = $2 }
  /^Gyroscopes calibration: residual / { gcost = $4 }
  END {
    n = split(substr(ths, 2), t, " ")
    printf "acc_threshold_multipliers"; for (i = 1; i <= n; i++) printf " %s", t[i]; print ""
    printf "acc_intervals_by_threshold"; for (i = 1; i <= n; i++) printf " %s", nint[t[i]]; print ""
    printf "acc_final_cost_by_threshold"; for (i = 1; i <= n; i++) printf " %s", cost[t[i]]; print ""
    print "acc_threshold_multiplier", best
    print "acc_static_intervals", nint[best]
    print "acc_final_cost", best_cost
    print "gyro_residual_blocks", gblocks
    print "gyro_initial_cost", ginit
    print "gyro_final_cost", gcost
    print "gyro_iterations", giter
    print "gyro_termination", gterm
  }' "$R/console.log")
num='[-+]?[0-9]+(\.[0-9]*)?([eE][-+]?[0-9]+)?'
for key in acc_threshold_multiplier acc_static_intervals acc_final_cost gyro_residual_blocks \
           gyro_initial_cost gyro_final_cost gyro_iterations; do
  printf '%s\n' "$figures" | grep -Eq "^$key $num\$" || die "could not parse $key from console.log"
done
for key in acc_threshold_multipliers acc_intervals_by_threshold acc_final_cost_by_threshold; do
  printf '%s\n' "$figures" | grep -Eq "^$key( ($num|nan))+\$" || die "could not parse $key from console.log"
done
printf '%s\n' "$figures" | grep -Eq '^gyro_termination [A-Z_]+$' || die "could not parse gyro_termination"

inv=$(awk '/inverse scale factors:/ { which = (/^Acc/ ? "acc" : "gyro"); n = 0; v = ""; next }
           which != "" && n < 3 { v = v " " $1; n++; if (n == 3) { print which "_inverse_scale" v; which = "" } }' \
      "$R/console.log")

eigen_ver=$(awk '/#define EIGEN_(WORLD|MAJOR|MINOR)_VERSION/ { v = v (v == "" ? "" : ".") $3 }
                 END { print (v == "" ? "unknown" : v) }' "$EIGEN_INC/Eigen/src/Core/util/Macros.h" 2>/dev/null \
            || echo unknown)
RES=$OUT/imu_tk_result.txt
{
cat <<EOF
# IMU-TK's own calibration of its own Xsens test recording (xsens_acc.mat, xsens_gyro.mat), reproduced.
# Produced by tests/data/imu_tk_xsens/reproduce_imu_tk.sh on $RESULT_DATE from IMU-TK commit
# ${COMMIT:0:7} ($COMMIT;
# IMU-TK by Alberto Pretto et al., BSD licence), running its example apps/test_imu_calib.cpp,
# unchanged in everything that affects the numbers (see the script's header for the build and
# the output-only changes): initial guesses acc bias 32768 counts, gyro scale 1/6258; gravity
# 9.81744 m/s^2; initial static interval 50 s; 100 samples per static interval; acc_use_means
# false; gyro dt from the timestamps; gyro bias not optimised.
# Built with Ceres $(sed -n 's/^Solver Summary (v \([0-9.]*\).*/\1/p' "$R/console.log" | head -n 1), Eigen ${eigen_ver}, $("$CXX" --version | head -n 1), -O3 -DNDEBUG.
# Data: $n_acc accelerometer and $n_gyro gyroscope samples (time in s, three raw counts).
#
# Model (include/imu_tk/calibration.h, CalibratedTriad_): for a raw reading X in counts,
#   X' = T * K * (X - B)
# T misalignment matrix, K = diag(s_x, s_y, s_z) scale matrix, B bias vector in counts. T is built as
#       [    1     -mis_yz   mis_zy ]
#   T = [  mis_xz     1     -mis_zx ]
#       [ -mis_xy   mis_yx     1    ]
# Accelerometers ("body" frame = accelerometer frame): mis_xz = mis_xy = mis_yx = 0, so T_a is unit
#   upper-triangular, T_a = [1 -mis_yz mis_zy; 0 1 -mis_zx; 0 0 1] (its (3,1) entry prints as -0);
#   a_calibrated = T_a * K_a * (raw_counts - b_a), K_a in m/s^2 per count, b_a in counts; estimated
#   by minimising sum (9.81744 - |a_calibrated|)^2 over 100 samples of each static interval.
# Gyroscopes (general case, all six mis_* free): w_calibrated = T_g * K_g * (raw_counts - b_g),
#   K_g in rad/s per count, b_g in counts = mean raw gyro counts over the first 50 s (not
#   optimised); T_g, K_g estimated by matching the gravity direction of consecutive static
#   intervals (normalised mean calibrated accelerations) through the integrated gyro rotation.
# Keys: *_misalignment = T (9 numbers, row-major); *_scale = diag(K) (3); *_bias = B (3);
#   *_inverse_scale = 1/diag(K) in counts per unit, as IMU-TK prints it.
# IMU-TK's figures: the accelerometer calibration is run for each static-detector threshold
#   multiplier (threshold = multiplier * |variance of the acc counts over the first 50 s|, 101-sample
#   window); intervals with >= 100 samples are used, >= 12 needed; the multiplier with the least
#   final cost is kept. Costs are Ceres final costs, 0.5 * sum of squared residuals
#   ((m/s^2)^2 for acc; gyro: unit-vector differences, unitless, one 3-residual block per pair of
#   consecutive static intervals). gyro_initial_cost is from Ceres' report (7 significant digits).
EOF
cat "$R/imu_tk_values.txt"
printf '%s\n' "$inv"
printf '%s\n' "$figures"
echo "n_samples_acc $n_acc"
echo "n_samples_gyro $n_gyro"
} > "$RES"

t_end=$(date +%s.%N)
echo "== IMU-TK's console summary (17 significant digits):"
sed -n '/^Accelerometers calibration: Better/,$p' "$R/console.log" \
  | sed '/^Solver Summary/,/^Termination:/d'
echo "== IMU-TK's .calib files (its own save(): misalignment, scale, bias):"
for f in test_imu_acc.calib test_imu_gyro.calib; do echo "-- $R/$f"; cat "$R/$f"; done
echo "== $RES:"
cat "$RES"
awk -v a="$t_start" -v b="$t_end" -v c="$t_run0" -v d="$t_run1" \
  'BEGIN { printf "== runtime: %.1f s total, %.2f s for the calibration run itself\n", b - a, d - c }'
