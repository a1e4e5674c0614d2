% Reference values for analysis/src/scales/jod.rs: JOD scaling, bootstrap intervals and the
% outlier analysis of pwcmp (github.com/mantiuk/pwcmp, commit 07876b2, MIT licence), run by
% GNU Octave 7.3.0 with octave-statistics (Debian 12).
%
% pwcmp calls MATLAB's optimoptions('fminunc', 'SpecifyObjectiveGradient', true, 'Display',
% 'off'), which Octave lacks; a shim on the path (shim/optimoptions.m) returns Octave's
% optimset('GradObj', 'on', 'Display', 'off', 'TolFun', 1e-14, 'TolX', 1e-14, 'MaxIter', 1e4,
% 'MaxFunEvals', 1e5) instead: the same objective and gradient, minimised by Octave's fminunc
% with tolerances tight enough that its stopping point is the minimum to far below 1e-3 JOD.
% pwcmp's code is not copied here.
%
% Run (from this folder), with pwcmp checked out in PWCMP and the shim in SHIM:
%   octave --no-gui --eval "addpath('SHIM'); addpath('PWCMP'); pwcmp_jod" > /dev/null
% Writes jod_pwcmp.json: per data set (pwcmp's examples/ex3_tmo_cmp_data.csv per scene and all
% scenes together; two simulated sets) the per-observer comparison matrices M (M(i,j): i was
% chosen over j), pw_scale's JOD, the bootstrap as pw_scale_bootstrp computes it (prctile 2.5
% and 97.5 and cov of pw_scale over resampled observers; the resamples are drawn here and
% written out so that the Rust side can use the same ones), and pw_outlier_analysis's L and
% dist_L.
pkg load statistics
rand('seed', 49); randn('seed', 49);
B = 40; % bootstrap resamples per data set (pw_scale_bootstrp's default use is 500)

function out = scale_set(name, MMs, conds, observers, B)
  % MMs: K x N*N, rows M(:)' per observer
  N = numel(conds);
  K = size(MMs, 1);
  M = reshape(sum(MMs, 1), N, N);
  jod = pw_scale(M);
  idx = randi(K, B, K);
  bst = zeros(B, N);
  for b = 1:B
    bst(b, :) = pw_scale(reshape(sum(MMs(idx(b, :), :), 1), N, N))';
  end
  [L, dist_L] = pw_outlier_analysis(MMs);
  out = struct();
  out.name = name;
  out.conditions = conds;
  out.observers = observers;
  ms = cell(K, 1);
  for k = 1:K
    ms{k} = reshape(MMs(k, :), N, N);
  end
  out.matrices = ms;
  out.jod = jod';
  out.resamples = idx - 1; % 0-based observer indices
  out.jod_low = prctile(bst, 2.5)';
  out.jod_high = prctile(bst, 97.5)';
  out.jod_cov = cov(bst);
  out.L = L';
  out.dist_L = dist_L';
end

% --- ex3: pwcmp's TMO comparisons (Eilertsen et al. 2013) ---
fid = fopen(fullfile(fileparts(which('pw_scale')), 'examples', 'ex3_tmo_cmp_data.csv'));
fgetl(fid);
cols = textscan(fid, '%s %f %s %s %s %f %s', 'Delimiter', ',');
fclose(fid);
[obs, ~, scene, ca, cb, sel] = deal(cols{1}, cols{2}, cols{3}, cols{4}, cols{5}, cols{6});
C = unique([ca; cb]);
N = numel(C);
S = unique(scene);
sets = {};
for g = 0:numel(S)
  if g == 0
    rows = true(size(obs)); name = 'ex3/all';
  else
    rows = strcmp(scene, S{g}); name = ['ex3/' S{g}];
  end
  O = unique(obs(rows));
  MMs = zeros(numel(O), N * N);
  for o = 1:numel(O)
    r = find(rows & strcmp(obs, O{o}));
    M = zeros(N, N);
    for kk = r'
      c1 = find(strcmp(ca{kk}, C)); c2 = find(strcmp(cb{kk}, C));
      if sel(kk)
        M(c1, c2) += 1;
      else
        M(c2, c1) += 1;
      end
    end
    MMs(o, :) = M(:)';
  end
  sets{end + 1} = scale_set(name, MMs, C', O', B);
end

% --- simulated: Thurstone observers (1 JOD = 75 %), incomplete designs, unanimous pairs ---
function MMs = simulate(q, K, pairs, reps)
  N = numel(q);
  MMs = zeros(K, N * N);
  for k = 1:K
    M = zeros(N, N);
    for p = 1:size(pairs, 1)
      i = pairs(p, 1); j = pairs(p, 2);
      for r = 1:reps
        if randn() * 1.4826 < q(i) - q(j)
          M(i, j) += 1;
        else
          M(j, i) += 1;
        end
      end
    end
    MMs(k, :) = M(:)';
  end
end
q1 = [0 0.4 1.1 1.5 2.8 4.5];
[a, b] = find(triu(ones(6), 1));
MMs = simulate(q1, 12, [a b], 1);
sets{end + 1} = scale_set('simulated/full', MMs, {'c1', 'c2', 'c3', 'c4', 'c5', 'c6'}, ...
                          arrayfun(@(k) sprintf('p%d', k), 1:12, 'UniformOutput', false), B);
q2 = [0 -0.7 0.6 1.9 2.2 3.0 3.4];
pairs2 = [1 2; 2 3; 3 4; 4 5; 5 6; 6 7; 1 3; 3 5; 5 7; 2 4; 4 6];
MMs = simulate(q2, 9, pairs2, 2);
sets{end + 1} = scale_set('simulated/incomplete', MMs, {'a', 'b', 'c', 'd', 'e', 'f', 'g'}, ...
                          arrayfun(@(k) sprintf('p%d', k), 1:9, 'UniformOutput', false), B);

out = struct('tool', 'pwcmp 07876b2 (github.com/mantiuk/pwcmp) under GNU Octave 7.3.0, statistics package', ...
             'sets', {sets});
fid = fopen('jod_pwcmp.json', 'w');
fprintf(fid, '%s\n', jsonencode(out));
fclose(fid);
