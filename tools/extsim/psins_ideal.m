% psins_ideal.m — error-free SIMU increments of a turntable attitude profile, computed with
% the PSINS toolbox's own Earth model and trajectory inversion (this project's driver; PSINS is
% fetched separately, see README.md — nothing of PSINS is in this repository).
%
%   octave-cli psins_ideal.m PSINS_ROOT ATT_CSV LAT_DEG LON_DEG H_M OUT
%
% ATT_CSV: header line, then rows  t_s, C_bn(1,1..3), C_bn(2,1..3), C_bn(3,1..3)
%          (body -> NED, the archive's convention), first row t = 0.
% OUT: an Octave binary file with  imu = [wm vm t]  (PSINS's raw angle and velocity
%      increments, rad and m/s, body axes = the archive's body axes, t = end of the interval)
%      and g, PSINS's normal gravity at the site (m/s^2).
%
% The loop is PSINS avp2imu (base/imu/avp2imu.m) for a static base with the attitude given as
% a matrix instead of PSINS Euler angles: PSINS's Euler set (pitch-roll-yaw about E-N-U) is
% singular where body y is vertical, which the factory sequences pass through while turning;
% avp2imu's own m2att/a2mat round trip would corrupt those samples.  Every step below is the
% avp2imu step with a2mat(avp(k,1:3)) replaced by the given C_nb.
args = argv();
if numel(args) ~= 6, error('usage: psins_ideal.m PSINS_ROOT ATT_CSV LAT_DEG LON_DEG H_M OUT'); end
root = args{1};
addpath(root); addpath(genpath(fullfile(root, 'base')));
more off;
glvs; global glv
A = dlmread(args{2}, ',', 1, 0);
pos = [str2double(args{3})*glv.deg; str2double(args{4})*glv.deg; str2double(args{5})];
T = [0 1 0; 1 0 0; 0 0 -1];          % NED -> ENU (PSINS's navigation frame)
len = size(A, 1);
ts = A(2,1) - A(1,1); ts2 = ts/2;
eth = earth(pos, [0;0;0]);            % static base: avp2imu's earth((pos_1+pos)/2, 0) is constant
Cnb_of = @(k) T*reshape(A(k,2:10), 3, 3)';
Cbn_1 = Cnb_of(1)';
wm_1 = [0;0;0]; vm_1 = [0;0;0];
imu = zeros(len-1, 7);
for k = 2:len
  Cnb = Cnb_of(k);
  phim = m2rv(Cbn_1*rv2m(eth.wnin*ts)*Cnb);
  wm = (glv.I33+askew(wm_1/12))^-1*phim;
  dvbm = Cbn_1*qmulv(rv2q(eth.wnin*ts2), -eth.gcc*ts);
  vm = (glv.I33+askew(wm/2+wm_1/12))^-1*(dvbm-cros(vm_1,wm)/12);
  imu(k-1,:) = [wm; vm; A(k,1)]';
  Cbn_1 = Cnb'; wm_1 = wm; vm_1 = vm;
end
g = eth.g; wnie = eth.wnie;
save('-binary', args{6}, 'imu', 'g', 'wnie');
