# rounds.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot rounds.gp
if (!exists("outfile")) outfile = "rounds.png"
set terminal pngcairo size 900,650 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set title "Rounds taken vs eq. 2.7 (p = 0.99; 3,000-point sparse map; min 200 rounds)"
set logscale y
set xlabel "wall fraction of the points (inlier ratio)"
set ylabel "rounds"
set grid
set key top right
set logscale x
plot "rounds.csv" skip 1 using 2:(strcol(1) eq "3d-uniform" ? $4 : NaN) with lines dt 2 lw 2 title "eq. 2.7, 3-point samples", "rounds.csv" skip 1 using 2:(strcol(1) eq "2d-uniform" ? $4 : NaN) with lines dt 2 lw 2 title "eq. 2.7, 2-point samples", "rounds.csv" skip 1 using 2:(strcol(1) eq "3d-uniform" ? $3 : NaN) with linespoints lw 2 title "3d-uniform (taken)", "rounds.csv" skip 1 using 2:(strcol(1) eq "3d-guided" ? $3 : NaN) with linespoints lw 2 title "3d-guided (taken)", "rounds.csv" skip 1 using 2:(strcol(1) eq "2d-uniform" ? $3 : NaN) with linespoints lw 2 title "2d-uniform (taken)", "rounds.csv" skip 1 using 2:(strcol(1) eq "2d-guided" ? $3 : NaN) with linespoints lw 2 title "2d-guided (taken)"
