# The rooms of drivers/ and what each may include (drivers/README.md; each room's README says the
# same in words; tools/room_graph.cmake holds the whole tree's rules). One static library per room,
# linked only to the rooms listed here (drivers/CMakeLists.txt derives the link lines from this graph).
#
# drivers/ may include calib/ and sequences/, never db/, station/ or tools/. The turntable's Modbus
# client needs nothing of ours; the IMU's CAN codec only calib/core's increment type and conventions
# (and links only that); the simulated station hardware drives the truth simulator from the table's
# motion and speaks through the two real drivers' protocols.
imucal_room(drivers/turntable LIBRARY imucal_turntable)
imucal_room(drivers/imu       LIBRARY imucal_imu       MAY_INCLUDE calib/core)
imucal_room(drivers/simulated LIBRARY imucal_simulated MAY_INCLUDE drivers/turntable drivers/imu calib/core calib/sim sequences)

imucal_room_rule(ROOMS drivers/turntable REACH_ONLY
                 BECAUSE "the turntable's driver includes nothing of ours")
imucal_room_rule(ROOMS drivers/imu REACH_ONLY calib/core sequences
                 BECAUSE "the IMU's driver includes calib/core only and links only that")
