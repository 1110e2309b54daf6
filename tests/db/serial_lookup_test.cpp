// Serial numbers, issue #50 item 3: one documented rule (db/history/serial_number.hpp). A lookup
// that misses only by case names the unit it missed ("did you mean SN-0001?") and never picks one
// (two units may differ only in case); every part of a serial between '-', '_' and '.' holds a
// letter or digit ("sn..1" was accepted).
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "db/history/serial_number.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using test::expect_throw_message;
using test::TempDir;

constexpr TimestampMs kT0Serial = 1714560000000;  // 2024-05-01T10:40:00Z

TEST(SerialLookup, AnotherCaseIsNotFoundAndTheMessageNamesTheUnitMeant) {
  TempDir dir;
  SqliteRepository repo(dir.file("serial.db"));
  const RunId id = repo.create_run(test::new_run("SN-0001", kT0Serial));
  repo.finish_run(id, test::pass_completion(1, kT0Serial + 60000));
  for (const std::function<void()>& lookup : std::vector<std::function<void()>>{
           [&] { (void)repo.history("sn-0001"); }, [&] { (void)repo.run_count("sn-0001"); },
           [&] { (void)repo.active_params("sn-0001"); }}) {
    const std::string msg = expect_throw_message<NotFound>(lookup);
    EXPECT_NE(msg.find("no unit with serial number \"sn-0001\""), std::string::npos) << msg;
    EXPECT_NE(msg.find("did you mean SN-0001?"), std::string::npos) << msg;
  }
  // The exact serial still finds its unit, and a serial unlike any says no more than before.
  EXPECT_EQ(repo.history("SN-0001").size(), 1u);
  const std::string none = expect_throw_message<NotFound>([&] { (void)repo.history("SN-0002"); });
  EXPECT_EQ(none.find("did you mean"), std::string::npos) << none;
}

TEST(SerialLookup, UnitsThatDifferOnlyInCaseAreAllNamedNoneChosen) {
  TempDir dir;
  SqliteRepository repo(dir.file("serial.db"));
  repo.create_run(test::new_run("Ab-1", kT0Serial));
  repo.create_run(test::new_run("AB-1", kT0Serial + 1000));
  EXPECT_EQ(repo.history("Ab-1").size(), 1u);
  EXPECT_EQ(repo.history("AB-1").size(), 1u);
  const std::string msg = expect_throw_message<NotFound>([&] { (void)repo.history("ab-1"); });
  EXPECT_NE(msg.find("did you mean AB-1 or Ab-1?"), std::string::npos) << msg;
}

struct SlipCase {
  std::string serial;
  std::string hint;  ///< what the message must name
};

class SerialSlipTest : public ::testing::TestWithParam<SlipCase> {};

TEST_P(SerialSlipTest, AnEmptyPartBetweenSeparatorsIsRefusedNamingWhere) {
  const SlipCase& c = GetParam();
  const std::optional<std::string> problem = serial_problem(c.serial);
  ASSERT_TRUE(problem.has_value()) << c.serial << " was accepted";
  EXPECT_NE(problem->find(c.hint), std::string::npos) << *problem;
  EXPECT_NE(problem->find(kSerialRule), std::string::npos) << *problem;
  TempDir dir;
  SqliteRepository repo(dir.file("serial.db"));
  EXPECT_THROW(repo.create_run(test::new_run(c.serial, kT0Serial)), InvalidInput);
}

INSTANTIATE_TEST_SUITE_P(Serials, SerialSlipTest,
                         ::testing::Values(SlipCase{"sn..1", "'..' at position 3"},
                                           SlipCase{"SN-", "ends with '-'"},
                                           SlipCase{"SN-_1", "'-_' at position 3"},
                                           SlipCase{"A--B", "'--' at position 2"},
                                           SlipCase{"SN.0001.", "ends with '.'"}));

TEST(SerialNumber, SeparatorsBetweenLettersAndDigitsAreAccepted) {
  for (const std::string s : {"SN-0001", "sn.1", "a_b.c-d", "0-0", "SIM-0001_rev.2"})
    EXPECT_FALSE(serial_problem(s).has_value()) << s << ": " << serial_problem(s).value_or("");
}

}  // namespace
}  // namespace imucal::db
