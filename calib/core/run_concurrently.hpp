#pragma once
// Two independent tasks at the same time: first() on the calling thread, second() on one
// std::thread (two threads at most: the station machines have two cores), then the exception of
// first(), else that of second(), is rethrown: the error a sequential first-then-second would meet
// first. Without a thread to start (resource limits), both run on the calling thread, second()
// first. One runner for the calibration pipeline and the archive reader (issue #22 item 6).
#include <exception>
#include <system_error>
#include <thread>

namespace imucal::calib::core {

template <typename First, typename Second>
void run_concurrently(First&& first, Second&& second) {
  std::exception_ptr second_error;
  auto guarded_second = [&] {
    try {
      second();
    } catch (...) {
      second_error = std::current_exception();
    }
  };
  std::thread worker;
  try {
    worker = std::thread(guarded_second);
  } catch (const std::system_error&) {
    guarded_second();  // no thread to be had: one after the other
  }
  std::exception_ptr first_error;
  try {
    first();
  } catch (...) {
    first_error = std::current_exception();
  }
  if (worker.joinable()) worker.join();
  if (first_error) std::rethrow_exception(first_error);
  if (second_error) std::rethrow_exception(second_error);
}

}  // namespace imucal::calib::core
