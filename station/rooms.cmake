# The rooms of station/, the daemon's library, and what each may include (station/README.md; each
# room's README says the same in words; tools/room_graph.cmake holds the whole tree's rules). One
# static library per room, linked only to the rooms listed here (station/CMakeLists.txt derives the
# link lines from this graph).
#
# station/ may include drivers/, db/, calib/ and sequences/, never tools/. Inside: the daemon's
# plumbing sits on the run, the run on the configuration and the control socket; the control socket
# knows the history and calib/core's types, not the run.
imucal_room(station/config  LIBRARY imucal_station_config
            MAY_INCLUDE drivers/turntable drivers/imu db/fleet calib/core calib/effects calib/diagnosis sequences)
imucal_room(station/control LIBRARY imucal_station_control
            MAY_INCLUDE db/history db/archive calib/core)
imucal_room(station/run     LIBRARY imucal_station_run
            MAY_INCLUDE station/config station/control drivers/turntable drivers/imu db/history db/archive
                        calib/core calib/nlsq calib/pipeline calib/diagnosis sequences)
imucal_room(station/daemon  LIBRARY imucal_station_daemon
            MAY_INCLUDE station/run station/control station/config db/history db/fleet sequences)
