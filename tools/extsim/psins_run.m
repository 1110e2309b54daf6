% psins_run.m — one PSINS SIMU run: the error-free increments of psins_ideal.m with the errors
% PSINS's imuerrset/imuadderr model (this project's driver; PSINS is fetched separately, see
% README.md).
%
%   octave-cli psins_run.m PSINS_ROOT IDEAL CFG_JSON OUT_TXT OUT_ERR_JSON
%
% CFG_JSON, in imuerrset's own units (keys absent = imuerrset argument not given):
%   seed            randn('state', seed)
%   eb [3] deg/h, db [3] ug, web deg/sqrt(h), wdb ug/sqrt(Hz)
%   sqrtR0G deg/h, TauG s, sqrtR0A ug, TauA s           (first-order Markov bias)
%   dKGii [3] ppm, dKAii [3] ppm, dKGij [6] arcsec, dKAij [3] arcsec
%   Ka2 [3] ug/g^2, rxyz [9] cm, dtGA ms               (imuerrset arguments 13-15)
%   Kap [3] ppm, gSens [9] deg/h/g (row-major)        (imuadderr fields Kap, gSens)
% OUT_TXT: wm(3) vm(3) t rows as imuadderr returns them.
% OUT_ERR_JSON: the error structure imuadderr used, in SI (what truth.json is made from).
args = argv();
if numel(args) ~= 5, error('usage: psins_run.m PSINS_ROOT IDEAL CFG_JSON OUT_TXT OUT_ERR_JSON'); end
root = args{1};
addpath(root); addpath(genpath(fullfile(root, 'base')));
pkg load signal   % imudot (inner lever arms) uses fir1/filtfilt
more off;
glvs; global glv
S = load(args{2}); imu = S.imu;
cfg = jsondecode(fileread(args{3}));
g = @(k, d) getfield_or(cfg, k, d);
function v = getfield_or(s, k, d)
  if isfield(s, k), v = s.(k); else, v = d; end
end
a = {g('eb',[0;0;0]), g('db',[0;0;0]), g('web',0), g('wdb',0), ...
     g('sqrtR0G',0), g('TauG',1000), g('sqrtR0A',0), g('TauA',1000), ...
     g('dKGii',[0;0;0]), g('dKAii',[0;0;0]), g('dKGij',zeros(6,1)), g('dKAij',zeros(3,1))};
nargs = 12;
if isfield(cfg,'Ka2') || isfield(cfg,'rxyz') || isfield(cfg,'dtGA'), nargs = 13; a{13} = g('Ka2',[0;0;0]); end
if isfield(cfg,'rxyz') || isfield(cfg,'dtGA'), nargs = 14; a{14} = g('rxyz',zeros(9,1)); end
if isfield(cfg,'dtGA'), nargs = 15; a{15} = cfg.dtGA; end
for k = 1:12, a{k} = a{k}(:); end
imuerr = imuerrset(a{1:nargs});
if isfield(cfg,'Kap'), imuerr.Kap = cfg.Kap(:)*glv.ppm; end
if isfield(cfg,'gSens'), imuerr.gSens = reshape(cfg.gSens(:), 3, 3)'*glv.dph/glv.g0; end
randn('state', cfg.seed); rand('state', cfg.seed);
out = imuadderr(imu, imuerr);
fid = fopen(args{4}, 'w');
fprintf(fid, '%.17g %.17g %.17g %.17g %.17g %.17g %.17g\n', out');
fclose(fid);
% the error structure in SI, for truth.json
e = struct();
e.eb = imuerr.eb; e.db = imuerr.db; e.web = imuerr.web; e.wdb = imuerr.wdb;
e.dKg = imuerr.dKg; e.dKa = imuerr.dKa; e.Ka2 = imuerr.Ka2;
e.sigma_g = imuerr.sqg.*sqrt(min(imuerr.taug,1e30)/2); e.tau_g = min(imuerr.taug, 1e30);
e.sigma_a = imuerr.sqa.*sqrt(min(imuerr.taua,1e30)/2); e.tau_a = min(imuerr.taua, 1e30);
if isfield(imuerr,'rx'), e.r = [imuerr.rx(:)'; imuerr.ry(:)'; imuerr.rz(:)']; end
if isfield(imuerr,'dtGA'), e.dtGA = imuerr.dtGA; end
if isfield(imuerr,'Kap'), e.Kap = imuerr.Kap; end
if isfield(imuerr,'gSens'), e.gSens = imuerr.gSens; end
e.g0 = glv.g0;
fid = fopen(args{5}, 'w'); fprintf(fid, '%s\n', jsonencode(e)); fclose(fid);
