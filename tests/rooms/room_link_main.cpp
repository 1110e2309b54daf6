// The room rules as a link error (ARCHITECTURE §2.3): tests/CMakeLists.txt links this empty program
// against one library room's whole archive and the libraries of the rooms its rooms.cmake lets it
// include, nothing more (room_link_<room>). Every object of the room is pulled in, so a call across
// the rule — an estimator into the simulator, db/ into station/, station/control into station/run —
// leaves an undefined reference and the build fails.
int main() { return 0; }
