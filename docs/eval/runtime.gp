# runtime.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot runtime.gp
if (!exists("outfile")) outfile = "runtime.png"
set terminal pngcairo size 1350,520 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set multiplot layout 1,3 title "Time per detection (one core; median over seeds)"
set logscale xy
set xlabel "points"
set ylabel "time [ms]"
set grid
set key top left font ",9"
set title "wall fraction 0.05"
plot "runtime.csv" skip 1 using 2:(strcol(1) eq "3d-uniform" && abs($3-0.05)<1e-9 ? $4 : NaN) with linespoints lw 2 title "3d-uniform", "" skip 1 using 2:(strcol(1) eq "3d-guided" && abs($3-0.05)<1e-9 ? $4 : NaN) with linespoints lw 2 title "3d-guided", "" skip 1 using 2:(strcol(1) eq "2d-uniform" && abs($3-0.05)<1e-9 ? $4 : NaN) with linespoints lw 2 title "2d-uniform", "" skip 1 using 2:(strcol(1) eq "2d-guided" && abs($3-0.05)<1e-9 ? $4 : NaN) with linespoints lw 2 title "2d-guided"
set title "wall fraction 0.1"
plot "runtime.csv" skip 1 using 2:(strcol(1) eq "3d-uniform" && abs($3-0.1)<1e-9 ? $4 : NaN) with linespoints lw 2 title "3d-uniform", "" skip 1 using 2:(strcol(1) eq "3d-guided" && abs($3-0.1)<1e-9 ? $4 : NaN) with linespoints lw 2 title "3d-guided", "" skip 1 using 2:(strcol(1) eq "2d-uniform" && abs($3-0.1)<1e-9 ? $4 : NaN) with linespoints lw 2 title "2d-uniform", "" skip 1 using 2:(strcol(1) eq "2d-guided" && abs($3-0.1)<1e-9 ? $4 : NaN) with linespoints lw 2 title "2d-guided"
set title "wall fraction 0.3"
plot "runtime.csv" skip 1 using 2:(strcol(1) eq "3d-uniform" && abs($3-0.3)<1e-9 ? $4 : NaN) with linespoints lw 2 title "3d-uniform", "" skip 1 using 2:(strcol(1) eq "3d-guided" && abs($3-0.3)<1e-9 ? $4 : NaN) with linespoints lw 2 title "3d-guided", "" skip 1 using 2:(strcol(1) eq "2d-uniform" && abs($3-0.3)<1e-9 ? $4 : NaN) with linespoints lw 2 title "2d-uniform", "" skip 1 using 2:(strcol(1) eq "2d-guided" && abs($3-0.3)<1e-9 ? $4 : NaN) with linespoints lw 2 title "2d-guided"
unset multiplot
