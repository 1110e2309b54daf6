// The room rule as a link error (calib/README.md): tests/CMakeLists.txt links this empty program
// against one room's whole archive and the rooms calib/rooms.cmake lets it include, nothing more.
// Every object of the room is pulled in, so a call from an estimator into the simulator (or from
// the simulator into anything but calib/core/) leaves an undefined reference and the build fails.
int main() { return 0; }
